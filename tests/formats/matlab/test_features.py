"""MATLAB constructs beyond the corpus: ode15i with decic, inline(), M \\ f, the Jacobian, explain import."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from odelab.experiment.keyref import explain
from odelab.experiment.loader import load_experiments
from odelab.formats import read
from odelab.run.runner import run_experiment


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_ode15i_with_decic_becomes_an_implicit_system_with_initial_fixed(tmp_path):
    path = _write(tmp_path, "weissinger.m", """\
f = @(t, y, yp) t*y^2*yp^3 - y^3*yp^2 + t*(t^2 + 1)*yp - t^2*y;
t0 = 1; y0 = sqrt(3/2); yp0 = 0;
[y0, yp0] = decic(f, t0, y0, 1, yp0, 0);
opts = odeset('RelTol', 1e-6, 'AbsTol', 1e-8);
[t, y] = ode15i(f, [1 10], y0, yp0, opts);
""")
    doc = read(path)
    assert not doc.gaps
    assert doc.data["system"] == {"states": ["y"], "kind": "implicit",
                                  "residuals": {"r1": "t*y^2*der(y)^3 - y^3*der(y)^2 + t*(t^2 + 1)*der(y) - t^2*y"}}
    assert doc.data["initial"] == {"y": np.sqrt(1.5), "der(y)": 0, "fixed": {"y": True}}
    (result,) = [r for e in load_experiments(path) for r in run_experiment(e)]
    exact = np.sqrt(result.t ** 2 + 0.5)
    units = np.max(np.abs(result.x[:, 0] - exact) / (1e-8 + 1e-6 * np.max(exact)))
    assert result.status == "success" and units < 20  # measured 3.6 tolerance units


def test_inline_functions_are_read_as_anonymous_functions(tmp_path):
    path = _write(tmp_path, "old.m", "f = inline('[u(2); 4*t-2*u(1)-u(2).*(4/5)]', 't', 'u');\n"
                                      "[T, U] = ode45(f, [0 13], [1 2], []);\ng = inline('-2*y + t');\n"
                                      "[T2, Y2] = ode23(g, [0 1], 1);\n")
    doc = read(path)
    assert not doc.gaps
    eqs = [p["system"]["equations"] for p in doc.data["problem"]]
    assert eqs[0] == {"u1": "u2", "u2": "4*t - 2*u1 - u2*0.8"}  # 4/5 of literals: the double MATLAB computes
    assert eqs[1] == {"y": "-2*y + t"}  # inline('-2*y + t'): its variables in MATLAB's alphabetical order, t, y


def test_a_mass_matrix_solved_in_the_right_hand_side_by_cramers_rule(tmp_path):
    path = _write(tmp_path, "cart.m", """\
[t, y] = ode45(@cart, [0 5], [0 0 0.3 0], odeset('RelTol', 1e-8, 'AbsTol', 1e-10));
function dy = cart(t, y)
M = [2, -0.5*cos(y(3)); -0.5*cos(y(3)), 0.4];
F = [-0.5*y(4)^2*sin(y(3)); -9.81*0.5*sin(y(3))];
a = M\\F;
dy = [y(2); a(1); y(4); a(2)];
end
""")
    (result,) = run_experiment(path)

    def f(t, y):
        M = np.array([[2, -0.5 * np.cos(y[2])], [-0.5 * np.cos(y[2]), 0.4]])
        a = np.linalg.solve(M, [-0.5 * y[3] ** 2 * np.sin(y[2]), -9.81 * 0.5 * np.sin(y[2])])
        return [y[1], a[0], y[3], a[1]]
    ref = solve_ivp(f, (0, 5), [0, 0, 0.3, 0], method="DOP853", t_eval=result.t, rtol=1e-12, atol=1e-14).y.T
    units = np.max(np.abs(result.x - ref) / (1e-10 + 1e-8 * np.max(np.abs(ref), axis=0)))
    assert units < 20


def test_an_analytic_jacobian_function_becomes_system_jacobian(tmp_path):
    path = _write(tmp_path, "vdpstiff.m", """\
function vdpstiff(MU)
if nargin < 1
  MU = 50;
end
options = odeset('Jacobian', @J, 'RelTol', 1e-4);
[t, y] = ode15s(@f, [0 20], [2; 0], options);
  function dydt = f(t, y)
    dydt = [y(2)
            MU*(1-y(1)^2)*y(2)-y(1)];
  end
  function dfdy = J(t, y)
    dfdy = [  0                  1
             -2*MU*y(1)*y(2)-1  MU*(1-y(1)^2) ];
  end
end
""")
    doc = read(path)
    assert not doc.gaps
    assert doc.data["system"]["jacobian"] == [[0, 1], ["-2*MU*y1*y2 - 1", "MU*(1 - y1^2)"]]
    assert doc.data["parameters"] == {"MU": 50}
    (result,) = run_experiment(path)
    assert result.status == "success"


def test_explain_import_says_what_the_matlab_reader_translates():
    text = explain("import")
    assert text.startswith("import  (odelab import FILE...") and "Exit 0: everything translated" in text
    matlab = explain("import.m")
    assert "(MATLAB's ballode) becomes the event's reset" in matlab and "Refused (exit 2): eval" in matlab
    with pytest.raises(LookupError, match="no import topic `import.xyz`"):
        explain("import.xyz")


def test_a_driver_function_takes_its_inputs_from_set_or_names_them_as_gaps(tmp_path):
    path = _write(tmp_path, "drv.m", "function drv(k, c)\nif nargin < 2\n  c = 0.1;\nend\n"
                                      "[t, y] = ode45(@(t, y) [y(2); -k*y(1) - c*y(2)], [0 5], [1 0]);\n")
    doc = read(path)
    assert "`k` is an input of drv(k, c) that the file does not set when called with none: give it with --set " \
           "k=VALUE" in doc.gaps[0].detail
    from odelab.formats.base import ImportOptions

    doc = read(path, ImportOptions(sets=(("k", "4"),)))
    assert not doc.gaps and doc.data["parameters"] == {"k": 4, "c": 0.1}


def test_eig_with_two_outputs_of_a_constant_matrix(tmp_path):
    path = _write(tmp_path, "modes.m", "K = [2 -1; -1 2];\n[V, D] = eig(K);\nw = sqrt(D(2,2));\n"
                                        "[t, y] = ode45(@(t, y) [y(2); -w^2*y(1)], [0 1], [1 0]);\n")
    doc = read(path)
    assert not doc.gaps and doc.data["parameters"] == {"w": np.sqrt(3.0)}  # ascending, as MATLAB's symmetric eig


def test_a_struct_array_of_parameter_sets_gives_one_case_each(tmp_path):
    (tmp_path / "decay_rhs.m").write_text("function dy = decay_rhs(t, y, p)\ndy = -p.k*y;\n")
    path = _write(tmp_path, "sets.m", "ks = [0.5 1 2];\nfor i = 1:3\n  pars(i).k = ks(i);\nend\n"
                                      "for i = 1:numel(pars)\n  [t, y] = ode45(@decay_rhs, [0 2], 1, [], pars(i));\nend\n")
    doc = read(path)
    assert not doc.gaps and doc.data["system"]["equations"] == {"y": "-pars_k*y"}
    assert [c["parameters"]["pars_k"] for c in doc.data["case"]] == [0.5, 1, 2]
    results = {r.case.name: r for r in run_experiment(path)}
    for name, k in (("ode45 i=1", 0.5), ("ode45 i=2", 1.0), ("ode45 i=3", 2.0)):
        r = results[name]
        assert np.max(np.abs(r.x[:, 0] - np.exp(-k * r.t))) < 10 * (1e-6 + 1e-3)  # ode45's defaults


def test_argument_defaults_of_a_driver_function(tmp_path):
    path = _write(tmp_path, "drv2.m", "function drv2(tf, opts)\n  arguments\n    tf (1,1) double = 3\n"
                                       "    opts.k (1,1) double = 4\n  end\n"
                                       "  [t, y] = ode45(@(t, y) -opts.k*y, [0 tf], 1);\nend\n")
    doc = read(path)
    assert not doc.gaps and doc.data["time"] == {"start": 0, "stop": 3}
    assert doc.data["parameters"] == {"opts_k": 4}
