"""``odelab network FILE.toml``: a network experiment file's derivation as text, nothing run.

Apart from :mod:`odelab.experiment.kinds.network` (which the loader calls to build a network
system) because this one calls the loader.
"""

from __future__ import annotations

from pathlib import Path

from odelab.exceptions import ExperimentError, InputError
from odelab.experiment import schema
from odelab.experiment.fields import expr
from odelab.experiment.loader import load_experiments
from odelab.experiment.kinds.network import network_of

__all__ = ["describe_file"]


def describe_file(path, width: int = 80) -> str:
    """The derivation of a network experiment file as text (``odelab network FILE.toml``).

    The file is loaded and checked as ``odelab run`` would (every case), and nothing runs. The
    first case's parameter values give the numeric A, B, C, D; cases with other parameter values
    are listed after it with their own matrices.
    """
    from odelab.systems.network.show import derivation_text, matrix_text

    try:
        experiments = load_experiments(path)
    except ExperimentError as exc:
        if not (exc.key or "").startswith("inputs"):
            raise
        # the elements written, the input signals not yet: the derivation needs no signal
        return _describe_base(Path(path), width)
    out = []
    for exp in experiments:
        problems = [c for c in exp.cases if c.problem.system.network is not None]
        if not problems:
            raise ExperimentError(f"{exp.source}: the system is not a network; `odelab network` shows the derivation "
                                  "of a kind = \"network\" file (for others, `odelab run` shows the equations).",
                                  key="system.kind")
        first = problems[0]
        out.append(f"{exp.title}\n({exp.source})\n")
        out.append(derivation_text(first.problem.system.network, first.problem.parameters, width=width))
        shown = {tuple(sorted(first.problem.parameters.items()))}
        for case in problems[1:]:
            key = tuple(sorted(case.problem.parameters.items()))
            if key in shown or not case.problem.system.network.derive().linear:
                continue
            shown.add(key)
            m = case.problem.system.network.matrices(case.problem.parameters)
            out.append(f"case {case.name}: " + ", ".join(f"{k} = {matrix_text(m[k].tolist())}" for k in "ABCD"
                                                         if m[k].size) + "\n")
    return "\n".join(out)


def _describe_base(path, width: int) -> str:
    """The derivation from a file's base tables alone (a file whose [inputs] are still missing)."""
    from odelab.formats.toml import read_toml
    from odelab.systems.network.show import derivation_text

    data, _ = read_toml(path)
    src = str(path)
    try:
        model = schema.Experiment.model_validate({k: v for k, v in data.items() if k not in ("case", "sweep", "study")})
    except Exception:  # the full loader's message is the one to show
        load_experiments(path)
        raise
    try:
        params = expr().evaluate_parameters(model.parameters) if model.parameters else {}
        net = network_of(model, params)
        text = derivation_text(net, params, width=width)
    except InputError as exc:
        raise exc.located(source=src) from None
    title = model.title or path.stem
    return f"{title}\n({path})\n\n{text}"
