"""MATLAB's built-in functions as odelab reads them: each computes on symbolic values, or says why it cannot.

- Mathematics maps onto odelab's expression language (``sin``, ``exp``, ``mod``, ``atan2``...; ``log2``,
  ``round``, ``hypot`` and the like are rewritten in its functions); on plain numbers it is computed.
- Arrays: ``zeros``, ``ones``, ``eye``, ``linspace`` (MATLAB's algorithm), ``size``, ``length``, ``sum``,
  ``norm``, ``dot``, ``cross``, ``diag``, ``reshape``, ``repmat``, ``inv``...
- The ODE suite: ``ode45`` and the rest (each call a case, see :mod:`.translate`), ``odeset``,
  ``odeget``, ``interp1`` of a table in t (an input), ``load`` of a numeric text file beside the file.
- Plotting and printing are ignored with a note; random numbers, file I/O, user input and the
  Symbolic Math Toolbox are unknown values (a gap where a case needs them).
- ``eval``, ``evalin``, ``assignin``, ``system``, ``unix``, ``dos`` and their kind are refused outright:
  odelab never runs a file's commands.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from odelab.exceptions import ExperimentError
from odelab.formats.base import IGNORED
from odelab.formats.matlab import nodes as n
from odelab.formats.matlab import ops
from odelab.formats.matlab.values import (
    Arr,
    Call,
    Cell,
    Const,
    FuncValue,
    Named,
    Op,
    SolverOutput,
    Str,
    Struct,
    StructArray,
    Sym,
    Unknown,
    Unsupported,
)

__all__ = ["BUILTINS", "SOLVERS", "PLOTTING", "command", "linspace"]

SOLVERS = ("ode45", "ode23", "ode113", "ode78", "ode89", "ode15s", "ode23s", "ode23t", "ode23tb", "ode15i")
UNSUPPORTED_SOLVERS = {"dde23": "a delay equation",
                       "ddesd": "a delay equation", "ddensd": "a neutral delay equation",
                       "bvp4c": "a boundary-value problem", "bvp5c": "a boundary-value problem",
                       "pdepe": "a partial differential equation", "ode": "MATLAB's ode object (R2023b)"}

PLOTTING = frozenset("""
plot plot3 semilogx semilogy loglog figure hold xlabel ylabel zlabel title legend grid subplot axis clf close
drawnow pause colorbar colormap text annotation line scatter scatter3 surf mesh contour contourf quiver quiver3
box fill area bar barh stairs stem errorbar sgtitle suptitle xlim ylim zlim view tiledlayout nexttile comet comet3
shg set gca gcf gco print saveas savefig movegui axes patch histogram hist pie polarplot polar fplot ezplot
odeplot odephas2 odephas3 odeprint linkaxes daspect pbaspect camlight lighting shading rotate3d zoom pan
animatedline addpoints getframe movie VideoWriter writeVideo open close figure frame xticks yticks zticks
xticklabels yticklabels caxis clim light material rectangle yyaxis streamline streamslice meshgrid ishold
gcbf uicontrol uimenu waitbar datetick
""".split())
PRINTING = frozenset("""
disp fprintf sprintf display num2str mat2str int2str format more diary echo clc home beep fflush printf puts
fputs fdisp
""".split())
IGNORED_CALLS = frozenset("""
clear clearvars close all warning tic toc clock cputime etime now datetime datestr date rng addpath rmpath
savepath cd pwd pkg narginchk nargchk nargoutchk validateattributes assert profile dbstop keyboard commandwindow
workspace whos who exist_file drawnow
""".split())
REFUSED = {"eval": "runs text as MATLAB code", "evalin": "runs text as MATLAB code",
           "evalc": "runs text as MATLAB code", "assignin": "writes into another workspace",
           "system": "runs a shell command", "unix": "runs a shell command", "dos": "runs a shell command",
           "perl": "runs a Perl script", "python": "runs Python code", "pyrun": "runs Python code",
           "pyrunfile": "runs Python code", "winopen": "opens a file in another program",
           "web": "opens a web page", "urlread": "reads the web", "webread": "reads the web",
           "urlwrite": "writes from the web", "websave": "writes from the web", "java": "runs Java",
           "javaObject": "runs Java", "javaMethod": "runs Java", "mex": "compiles and runs C",
           "loadlibrary": "loads a native library", "calllib": "calls a native library", "delete": "deletes files",
           "rmdir": "deletes folders", "movefile": "moves files", "copyfile": "copies files", "mkdir": "makes folders",
           "run": "runs a script by its path", "builtin": "calls a function by a computed name"}
RANDOM = frozenset("rand randn randi randperm normrnd unifrnd".split())
FILE_IO = frozenset("""
fopen fclose fread fwrite fscanf fgetl fgets textscan xlsread xlsx readtable readcell writetable writematrix
writecell csvwrite dlmwrite save xlswrite audioread imread imwrite fileread exportgraphics
""".split())
SYMBOLIC = frozenset("syms sym subs dsolve matlabFunction simplify vpa solve odeToVectorField symfun".split())
INTERACTIVE = frozenset("input keyboard ginput inputdlg questdlg menu uiwait waitforbuttonpress".split())

BUILTINS: dict[str, Callable] = {}


def builtin(*names: str):
    def register(fn):
        for name in names:
            BUILTINS[name] = fn
        return fn
    return register


def _arr(interp, value, what: str = "an argument") -> Arr:
    if isinstance(value, SolverOutput):
        from odelab.formats.matlab.results import result_numbers

        numbers = result_numbers(value)
        if numbers is not None:
            return numbers
    return interp.numeric(value, what)


def _first_unknown(args) -> Unknown | None:
    for a in args:
        if isinstance(a, Unknown):
            return a
    return None


def _scalar_int(interp, value, what: str) -> int:
    arr = _arr(interp, value, what)
    number = arr.scalar_value()
    if number is None or not math.isfinite(number) or number != int(number):
        raise Unsupported(f"{what} must be a constant whole number")
    return int(number)


# --- constants ----------------------------------------------------------------------------------------


def _constant(value: float, named: str | None = None):
    def handler(interp, args, nargout, node, scope):
        if args:
            dims = _dims(interp, args)
            ops.check_elements(dims[0] * dims[1])
            return [Arr.numeric(np.full(dims, value))]
        return [Arr.scalar(Named(named, value)) if named else Arr.numeric(value)]
    return handler


BUILTINS["pi"] = _constant(math.pi, "pi")
BUILTINS["eps"] = _constant(float(np.finfo(float).eps))
for _name in ("Inf", "inf"):
    BUILTINS[_name] = _constant(math.inf)
for _name in ("NaN", "nan"):
    BUILTINS[_name] = _constant(math.nan)
BUILTINS["realmax"] = _constant(float(np.finfo(float).max))
BUILTINS["realmin"] = _constant(float(np.finfo(float).tiny))


@builtin("true")
def _true(interp, args, nargout, node, scope):
    out = Arr.numeric(1.0)
    out.logical = True
    return [out]


@builtin("false")
def _false(interp, args, nargout, node, scope):
    out = Arr.numeric(0.0)
    out.logical = True
    return [out]


@builtin("i", "j", "1i", "complex", "imag", "real", "conj", "angle")
def _complex(interp, args, nargout, node, scope):
    raise Unsupported("complex numbers are not translated (odelab integrates real states)")


# --- elementwise mathematics ----------------------------------------------------------------------------


def _map(build: Callable[..., Sym], numeric: Callable | None, arity: tuple[int, int] = (1, 1)):
    def handler(interp, args, nargout, node, scope):
        name = node.target.name if isinstance(node, n.Index) else getattr(node, "name", "?")
        if not arity[0] <= len(args) <= arity[1]:
            raise Unsupported(f"`{name}` with {len(args)} arguments is not translated")
        unknown = _first_unknown(args)
        if unknown is not None:
            return [unknown]
        arrays = [_arr(interp, a) for a in args]
        rows, cols = arrays[0].shape
        for a in arrays[1:]:
            rows, cols = ops._broadcast((rows, cols), a.shape)
        if numeric is not None and all(a.data is not None for a in arrays):
            with np.errstate(all="ignore"):
                data = numeric(*[a.data for a in arrays])
            return [Arr.numeric(np.broadcast_to(np.asarray(data, dtype=float), (rows, cols)))]
        items = [build(*[ops._at(a, i, j) for a in arrays]) for j in range(cols) for i in range(rows)]
        return [Arr.of_items(rows, cols, items)]
    return handler


def _odelab(fn: str):
    return lambda *a: Call(fn, a)


_NUMPY_OF = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
             "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp, "log": np.log, "log10": np.log10,
             "sqrt": np.sqrt, "abs": np.abs, "sign": np.sign, "floor": np.floor, "ceil": np.ceil}
for _fn, _np in _NUMPY_OF.items():
    BUILTINS[_fn] = _map(_odelab(_fn), _np)
BUILTINS["realsqrt"] = BUILTINS["sqrt"]
BUILTINS["reallog"] = BUILTINS["log"]
BUILTINS["atan2"] = _map(_odelab("atan2"), np.arctan2, (2, 2))
BUILTINS["heaviside"] = _map(_odelab("heaviside"), lambda x: np.heaviside(x, 0.5))
BUILTINS["square"] = _map(_odelab("square"), None, (1, 2))  # the Signal Processing Toolbox's, as odelab's
BUILTINS["sawtooth"] = _map(_odelab("sawtooth"), None, (1, 2))


def _mod_numeric(a, m):
    with np.errstate(all="ignore"):
        return np.where(m == 0, a, np.mod(a, np.where(m == 0, 1.0, m)))


BUILTINS["mod"] = _map(_odelab("mod"), _mod_numeric, (2, 2))
BUILTINS["rem"] = _map(_odelab("rem"), np.fmod, (2, 2))
BUILTINS["power"] = _map(lambda a, b: Op("^", a, b), np.power, (2, 2))
BUILTINS["times"] = _map(lambda a, b: Op("*", a, b), np.multiply, (2, 2))
BUILTINS["rdivide"] = _map(lambda a, b: Op("/", a, b), np.divide, (2, 2))
BUILTINS["ldivide"] = _map(lambda a, b: Op("/", b, a), lambda a, b: np.divide(b, a), (2, 2))
BUILTINS["plus"] = _map(lambda a, b: Op("+", a, b), np.add, (2, 2))
BUILTINS["minus"] = _map(lambda a, b: Op("-", a, b), np.subtract, (2, 2))
BUILTINS["uminus"] = _map(lambda a: Op("neg", a), np.negative)
BUILTINS["log2"] = _map(lambda x: Op("/", Call("log", (x,)), Call("log", (Const(2.0),))), np.log2)
BUILTINS["log1p"] = _map(lambda x: Call("log", (Op("+", Const(1.0), x),)), np.log1p)
BUILTINS["expm1"] = _map(lambda x: Op("-", Call("exp", (x,)), Const(1.0)), np.expm1)
BUILTINS["sec"] = _map(lambda x: Op("/", Const(1.0), Call("cos", (x,))), lambda x: 1 / np.cos(x))
BUILTINS["csc"] = _map(lambda x: Op("/", Const(1.0), Call("sin", (x,))), lambda x: 1 / np.sin(x))
BUILTINS["cot"] = _map(lambda x: Op("/", Const(1.0), Call("tan", (x,))), lambda x: 1 / np.tan(x))
BUILTINS["asinh"] = _map(lambda x: Call("log", (Op("+", x, Call("sqrt", (Op("+", Op("^", x, Const(2.0)),
                                                                                   Const(1.0)),))),)), np.arcsinh)
BUILTINS["acosh"] = _map(lambda x: Call("log", (Op("+", x, Call("sqrt", (Op("-", Op("^", x, Const(2.0)),
                                                                                   Const(1.0)),))),)), np.arccosh)
BUILTINS["atanh"] = _map(lambda x: Op("*", Const(0.5), Call("log", (Op("/", Op("+", Const(1.0), x),
                                                                          Op("-", Const(1.0), x)),))), np.arctanh)
BUILTINS["fix"] = _map(lambda x: Op("*", Call("sign", (x,)), Call("floor", (Call("abs", (x,)),))), np.trunc)
BUILTINS["round"] = _map(lambda x: Op("*", Call("sign", (x,)), Call("floor", (Op("+", Call("abs", (x,)),
                                                                               Const(0.5)),))),
                         lambda x: np.sign(x) * np.floor(np.abs(x) + 0.5))
BUILTINS["hypot"] = _map(lambda a, b: Call("sqrt", (Op("+", Op("^", a, Const(2.0)), Op("^", b, Const(2.0))),)),
                         np.hypot, (2, 2))
BUILTINS["nthroot"] = _map(lambda x, k: Op("*", Call("sign", (x,)), Op("^", Call("abs", (x,)),
                                                                         Op("/", Const(1.0), k))),
                           lambda x, k: np.sign(x) * np.abs(x) ** (1.0 / k), (2, 2))
_DEG = math.pi / 180.0
for _fn in ("sin", "cos", "tan"):
    BUILTINS[_fn + "d"] = _map((lambda f: lambda x: Call(f, (Op("*", x, Op("/", Named("pi", math.pi),
                                                                            Const(180.0))),)))(_fn),
                               (lambda f: lambda x: _NUMPY_OF[f](x * _DEG))(_fn))
for _fn, _np in (("asin", np.arcsin), ("acos", np.arccos), ("atan", np.arctan)):
    BUILTINS[_fn + "d"] = _map((lambda f: lambda x: Op("*", Call(f, (x,)), Op("/", Const(180.0),
                                                                         Named("pi", math.pi))))(_fn),
                               (lambda g: lambda x: np.rad2deg(g(x)))(_np))
BUILTINS["atan2d"] = _map(lambda a, b: Op("*", Call("atan2", (a, b)), Op("/", Const(180.0), Named("pi", math.pi))),
                          lambda a, b: np.rad2deg(np.arctan2(a, b)), (2, 2))
BUILTINS["stepfun"] = _map(lambda x, x0: Op(">=", x, x0), lambda x, x0: (x >= x0).astype(float), (2, 2))
BUILTINS["deg2rad"] = _map(lambda x: Op("*", x, Op("/", Named("pi", math.pi), Const(180.0))), np.deg2rad)
BUILTINS["rad2deg"] = _map(lambda x: Op("*", x, Op("/", Const(180.0), Named("pi", math.pi))), np.rad2deg)
BUILTINS["double"] = BUILTINS["full"] = BUILTINS["squeeze"] = _map(lambda x: x, lambda x: x)
BUILTINS["logical"] = _map(ops.truth, lambda x: (x != 0).astype(float))
BUILTINS["not"] = _map(lambda x: ops._not(x), lambda x: (x == 0).astype(float))


@builtin("min", "max")
def _minmax(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    unknown = _first_unknown(args)
    if unknown is not None:
        return [unknown]
    if len(args) == 2 and not (isinstance(args[1], Arr) and args[1].size == 0):
        return _map(_odelab(name), np.minimum if name == "min" else np.maximum, (2, 2))(interp, args, 1, node, scope)
    if not args:
        raise Unsupported(f"`{name}` needs an argument")
    a = _arr(interp, args[0])
    if len(args) == 3:
        dim = _scalar_int(interp, args[2], f"`{name}`'s dimension")
        a = a if dim == 1 else ops.transpose(a)
        result = _reduce_columns(a, lambda items: _chain(name, items))
        return [result if dim == 1 else ops.transpose(result)]
    if a.data is not None and a.size:
        values = a.data if a.rows > 1 and a.cols > 1 else a.data.reshape(1, -1)
        best = values.min(axis=0) if name == "min" else values.max(axis=0)
        outputs = [Arr.numeric(best.reshape(1, -1))]
        if nargout > 1:
            where = values.argmin(axis=0) if name == "min" else values.argmax(axis=0)
            outputs.append(Arr.numeric((where + 1.0).reshape(1, -1)))
        return outputs
    if nargout > 1:
        raise Unsupported(f"`[value, index] = {name}(...)` of values that depend on the state")
    vector = a if (a.rows > 1 and a.cols > 1) else Arr(a.size, 1, items=a.all_items())
    return [_reduce_columns(vector, lambda items: _chain(name, items))]


def _chain(name: str, items: list[Sym]) -> Sym:
    if len(items) == 1:
        return items[0]
    return Call(name, tuple(items)) if len(items) <= 8 else _fold(name, items)


def _fold(name, items):
    out = items[0]
    for item in items[1:]:
        out = Call(name, (out, item))
    return out


def _reduce_columns(a: Arr, reduce: Callable[[list[Sym]], Sym]) -> Arr:
    if a.rows == 1 or a.cols == 1:
        return Arr.of_items(1, 1, [reduce(a.all_items())]) if a.size else Arr.numeric(np.zeros((1, 0)))
    out = [reduce([a.item(j * a.rows + i) for i in range(a.rows)]) for j in range(a.cols)]
    return Arr.of_items(1, a.cols, out)


def _sum_items(items: list[Sym]) -> Sym:
    if not items:
        return Const(0.0)
    total = items[0]
    for item in items[1:]:
        total = Op("+", total, item)
    return total


def _prod_items(items: list[Sym]) -> Sym:
    if not items:
        return Const(1.0)
    total = items[0]
    for item in items[1:]:
        total = Op("*", total, item)
    return total


def _reducer(build, numeric):
    def handler(interp, args, nargout, node, scope):
        unknown = _first_unknown(args)
        if unknown is not None:
            return [unknown]
        a = _arr(interp, args[0])
        if len(args) > 1:
            dim = _scalar_int(interp, args[1], "the dimension")
            if dim == 2:
                a = ops.transpose(a)
                if a.data is not None:
                    return [Arr.numeric(numeric(a.data, axis=0).reshape(-1, 1))]
                return [ops.transpose(_reduce_columns(a if a.rows > 1 else Arr(a.size, 1, items=a.all_items()),
                                                      build))]
        if a.data is not None:
            values = a.data if a.rows > 1 and a.cols > 1 else a.data.reshape(-1, 1)
            return [Arr.numeric(numeric(values, axis=0).reshape(1, -1))]
        return [_reduce_columns(a, build)]
    return handler


BUILTINS["sum"] = _reducer(_sum_items, np.sum)
BUILTINS["prod"] = _reducer(_prod_items, np.prod)
BUILTINS["mean"] = _reducer(lambda items: Op("/", _sum_items(items), Const(float(len(items)))), np.mean)


@builtin("norm")
def _norm(interp, args, nargout, node, scope):
    a = _arr(interp, args[0])
    if len(args) > 1:
        p = _arr(interp, args[1]).scalar_value()
        if p not in (2.0,):
            if a.data is not None:
                return [Arr.numeric(np.linalg.norm(a.data.reshape(-1), p))]
            raise Unsupported("`norm(x, p)` with p other than 2 of values that depend on the state")
    if a.data is not None:
        return [Arr.numeric(np.linalg.norm(a.data if a.rows > 1 and a.cols > 1 else a.data.reshape(-1)))]
    if a.rows > 1 and a.cols > 1:
        raise Unsupported("the norm of a matrix that depends on the state")
    return [Arr.scalar(Call("sqrt", (_sum_items([Op("^", x, Const(2.0)) for x in a.all_items()]),)))]


@builtin("dot")
def _dot(interp, args, nargout, node, scope):
    a, b = _arr(interp, args[0]), _arr(interp, args[1])
    if a.size != b.size:
        raise Unsupported("`dot` of vectors of different lengths")
    if a.data is not None and b.data is not None:
        return [Arr.numeric(float(np.dot(a.data.reshape(-1), b.data.reshape(-1))))]
    terms = [ops._term(x, y) for x, y in zip(a.all_items(), b.all_items())]
    return [Arr.scalar(_sum_items([t for t in terms if t is not None]))]


@builtin("cross")
def _cross(interp, args, nargout, node, scope):
    a, b = _arr(interp, args[0]), _arr(interp, args[1])
    if a.size != 3 or b.size != 3:
        raise Unsupported("`cross` of vectors that are not 3 long")
    x, y = a.all_items(), b.all_items()
    items = [Op("-", Op("*", x[1], y[2]), Op("*", x[2], y[1])), Op("-", Op("*", x[2], y[0]), Op("*", x[0], y[2])),
             Op("-", Op("*", x[0], y[1]), Op("*", x[1], y[0]))]
    return [Arr.of_items(a.rows, a.cols, items)]


# --- constructors and shapes ----------------------------------------------------------------------------


def _dims(interp, args) -> tuple[int, int]:
    numbers = [_arr(interp, a, "a size") for a in args]
    if len(numbers) == 1:
        values = numbers[0].numbers()
        if values is None:
            raise Unsupported("a size that depends on the state")
        flat = values.reshape(-1)
        dims = (flat[0], flat[0]) if flat.size == 1 else tuple(flat[:2])
    else:
        dims = tuple(_scalar_int(interp, a, "a size") for a in args[:2])
        if len(args) > 2 and any(_scalar_int(interp, a, "a size") != 1 for a in args[2:]):
            raise Unsupported("arrays of more than two dimensions are not translated")
    rows, cols = (max(int(d), 0) for d in dims)
    ops.check_elements(float(rows) * float(cols))
    return rows, cols


def _filled(value: float):
    def handler(interp, args, nargout, node, scope):
        args = [a for a in args if not (isinstance(a, Str))]  # zeros(2, 1, 'like', x), 'double'
        rows, cols = _dims(interp, args) if args else (1, 1)
        return [Arr.numeric(np.full((rows, cols), value))]
    return handler


BUILTINS["zeros"] = _filled(0.0)
BUILTINS["ones"] = _filled(1.0)


@builtin("eye")
def _eye(interp, args, nargout, node, scope):
    rows, cols = _dims(interp, args) if args else (1, 1)
    return [Arr.numeric(np.eye(rows, cols))]


def linspace(d1: float, d2: float, count: int) -> np.ndarray:
    """MATLAB's linspace (R2016a and later), bit for bit: d1 + (0:n-1)*(d2 - d1)/(n-1), both ends exact."""
    if count < 1:
        return np.zeros(0)
    n1 = count - 1
    if n1 == 0:
        return np.array([d2], dtype=float)
    k = np.arange(count, dtype=float)
    c = (d2 - d1) * (n1 - 1)
    with np.errstate(all="ignore"):
        if math.isinf(c):
            if math.isinf(d2 - d1):
                y = d1 + (d2 / n1) * k - (d1 / n1) * k
            else:
                y = d1 + k * ((d2 - d1) / n1)
        else:
            y = d1 + k * (d2 - d1) / n1
    if d1 == d2:
        y[:] = d1
    else:
        y[0] = d1
        y[-1] = d2
    return y


@builtin("linspace")
def _linspace(interp, args, nargout, node, scope):
    unknown = _first_unknown(args)
    if unknown is not None:
        return [unknown]
    d1 = _arr(interp, args[0]).scalar_value()
    d2 = _arr(interp, args[1]).scalar_value()
    if d1 is None or d2 is None:
        raise Unsupported("linspace between values that are not constant")
    count = _scalar_int(interp, args[2], "linspace's number of points") if len(args) > 2 else 100
    ops.check_elements(count, "linspace")
    return [Arr.numeric(linspace(d1, d2, count).reshape(1, -1))]


@builtin("logspace")
def _logspace(interp, args, nargout, node, scope):
    d1, d2 = (_arr(interp, a).scalar_value() for a in args[:2])
    count = _scalar_int(interp, args[2], "logspace's number of points") if len(args) > 2 else 50
    ops.check_elements(count, "logspace")
    return [Arr.numeric((10.0 ** linspace(d1, d2, count)).reshape(1, -1))]


@builtin("size")
def _size(interp, args, nargout, node, scope):
    value = args[0]
    if isinstance(value, SolverOutput):
        from odelab.formats.matlab.results import result_count

        dim = _scalar_int(interp, args[1], "size's dimension") if len(args) > 1 else 1
        if value.kind in ("t", "y") and dim == 1:
            return [result_count(value)]
        if value.kind == "y" and dim == 2:
            return [Arr.numeric(float(value.call.states))]
        return [Unknown("the size of a solver's output", node.line, scope.file)]
    if isinstance(value, Unknown):
        return [value]
    rows, cols = _shape_of(interp, value)
    if len(args) > 1:
        dim = _scalar_int(interp, args[1], "size's dimension")
        return [Arr.numeric(float(rows if dim == 1 else cols if dim == 2 else 1))]
    if nargout >= 2:
        return [Arr.numeric(float(rows)), Arr.numeric(float(cols))] + [Arr.numeric(1.0)] * (nargout - 2)
    return [Arr.numeric([[float(rows), float(cols)]])]


def _shape_of(interp, value) -> tuple[int, int]:
    if isinstance(value, Arr):
        return value.shape
    if isinstance(value, Cell):
        return value.rows, value.cols
    if isinstance(value, Str):
        return (1, len(value.text))
    if isinstance(value, (Struct, FuncValue)):
        return (1, 1)

    if isinstance(value, StructArray):
        return (1, len(value.items))
    raise Unsupported(interp.why_not_number(value, "an array"))


@builtin("length", "numel")
def _length(interp, args, nargout, node, scope):
    value = args[0]
    name = node.target.name if isinstance(node, n.Index) else node.name
    if isinstance(value, SolverOutput):
        from odelab.formats.matlab.results import result_count

        if value.kind in ("t", "y"):
            return [result_count(value)]
        return [Unknown("the size of a solver's output", node.line, scope.file)]
    if isinstance(value, Unknown):
        return [value]
    rows, cols = _shape_of(interp, value)
    count = rows * cols if name == "numel" else (0 if rows * cols == 0 else max(rows, cols))
    return [Arr.numeric(float(count))]


@builtin("isempty")
def _isempty(interp, args, nargout, node, scope):
    value = args[0]
    if isinstance(value, (Unknown, SolverOutput)):
        return [Unknown("whether a value odelab cannot know is empty", node.line, scope.file)]
    rows, cols = _shape_of(interp, value)
    return [Arr.numeric(float(rows * cols == 0))]


def _predicate(test: Callable[[Any], bool]):
    def handler(interp, args, nargout, node, scope):
        if isinstance(args[0], Unknown):
            return [args[0]]
        return [Arr.numeric(float(test(args[0])))]
    return handler


BUILTINS["isnumeric"] = _predicate(lambda v: isinstance(v, Arr) and not v.is_char)
BUILTINS["isreal"] = _predicate(lambda v: isinstance(v, Arr))
BUILTINS["isfloat"] = BUILTINS["isnumeric"]
BUILTINS["ischar"] = _predicate(lambda v: isinstance(v, Str))
BUILTINS["isstring"] = BUILTINS["ischar"]
BUILTINS["isstruct"] = _predicate(lambda v: isinstance(v, Struct))
BUILTINS["iscell"] = _predicate(lambda v: isinstance(v, Cell))
BUILTINS["isa"] = _predicate(lambda v: isinstance(v, FuncValue))
BUILTINS["is_function_handle"] = BUILTINS["isa"]
BUILTINS["isscalar"] = _predicate(lambda v: isinstance(v, Arr) and v.size == 1)
BUILTINS["isvector"] = _predicate(lambda v: isinstance(v, Arr) and (v.rows == 1 or v.cols == 1) and v.size >= 1)
BUILTINS["isrow"] = _predicate(lambda v: isinstance(v, Arr) and v.rows == 1)
BUILTINS["iscolumn"] = _predicate(lambda v: isinstance(v, Arr) and v.cols == 1)


@builtin("isfield")
def _isfield(interp, args, nargout, node, scope):
    if not isinstance(args[0], Struct) or not isinstance(args[1], Str):
        return [Arr.numeric(0.0)]
    return [Arr.numeric(float(args[1].text in args[0].fields))]


@builtin("exist")
def _exist(interp, args, nargout, node, scope):
    if not args or not isinstance(args[0], Str):
        raise Unsupported("exist of a name that is not a constant string")
    name = args[0].text
    if scope.has(name, interp.globals):
        return [Arr.numeric(1.0)]
    if interp.find_function(name, scope) is not None:
        return [Arr.numeric(2.0)]
    return [Arr.numeric(5.0 if name in BUILTINS else 0.0)]


@builtin("nargin")
def _nargin(interp, args, nargout, node, scope):
    if args:
        raise Unsupported("nargin of another function")
    return [Arr.numeric(float(scope.nargin))]


@builtin("nargout")
def _nargout(interp, args, nargout, node, scope):
    return [Arr.numeric(float(scope.nargout))]


@builtin("diag")
def _diag(interp, args, nargout, node, scope):
    a = _arr(interp, args[0])
    if a.rows == 1 or a.cols == 1:
        items = a.all_items()
        size = len(items)
        out = [Const(0.0)] * (size * size)
        for k, item in enumerate(items):
            out[k * size + k] = item
        return [Arr.of_items(size, size, out)]
    size = min(a.rows, a.cols)
    return [Arr.of_items(size, 1, [a.item(k * a.rows + k) for k in range(size)])]


@builtin("reshape")
def _reshape(interp, args, nargout, node, scope):
    a = _arr(interp, args[0])
    dims = [d for d in args[1:]]
    if len(dims) == 1:
        rows, cols = _dims(interp, dims)
    else:
        known = [None if isinstance(d, Arr) and d.size == 0 else _scalar_int(interp, d, "a size") for d in dims[:2]]
        if known[0] is None:
            known[0] = a.size // known[1]
        if known[1] is None:
            known[1] = a.size // known[0]
        rows, cols = known
    if rows * cols != a.size:
        raise Unsupported(f"reshape of {a.size} elements to {rows}x{cols}")
    return [Arr.of_items(rows, cols, a.all_items()) if a.data is None else
            Arr.numeric(a.data.T.reshape(-1).reshape(cols, rows).T)]


@builtin("repmat")
def _repmat(interp, args, nargout, node, scope):
    a = _arr(interp, args[0])
    reps = _dims(interp, args[1:])
    ops.check_elements(a.size * reps[0] * reps[1])
    rows = [[a] * reps[1] for _ in range(reps[0])]
    return [ops.concat(rows)]


@builtin("transpose", "ctranspose")
def _transpose(interp, args, nargout, node, scope):
    return [ops.transpose(_arr(interp, args[0]))]


@builtin("horzcat", "vertcat", "cat")
def _cat(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    if name == "cat":
        dim = _scalar_int(interp, args[0], "cat's dimension")
        args = args[1:]
        name = "vertcat" if dim == 1 else "horzcat"
    arrays = [_arr(interp, a) for a in args]
    return [ops.concat([arrays] if name == "horzcat" else [[a] for a in arrays])]


@builtin("inv")
def _inv(interp, args, nargout, node, scope):
    numbers = _arr(interp, args[0]).numbers()
    if numbers is None or numbers.shape[0] != numbers.shape[1]:
        raise Unsupported("the inverse of a matrix that depends on the state; give it as odeset's Mass instead")
    return [Arr.numeric(np.linalg.inv(numbers))]


@builtin("eig")
def _eig(interp, args, nargout, node, scope):
    """``eig(A)`` and ``[V, D] = eig(A)`` of a constant matrix with real eigenvalues."""
    numbers = _arr(interp, args[0]).numbers() if args else None
    if numbers is None or len(args) > 1 or numbers.shape[0] != numbers.shape[1]:
        raise Unsupported("eig of a square constant matrix (one argument) only")
    if np.array_equal(numbers, numbers.T):  # MATLAB's eig of a symmetric matrix: ascending, as LAPACK's dsyev
        values, vectors = np.linalg.eigh(numbers)
    else:
        values, vectors = np.linalg.eig(numbers)
    if np.any(np.abs(values.imag) > 0) or np.any(np.abs(vectors.imag) > 0):
        raise Unsupported("eig with complex eigenvalues is not translated (odelab's values are real)")
    if nargout < 2:
        return [Arr.numeric(values.real.reshape(-1, 1))]
    return [Arr.numeric(vectors.real), Arr.numeric(np.diag(values.real))]


@builtin("det", "trace", "expm", "rank", "cond", "pinv", "null", "kron", "cumsum", "cumprod", "diff",
         "flipud", "fliplr", "flip", "sort", "unique", "find", "any", "all", "trapz", "std", "var", "median")
def _numeric_only(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    unknown = _first_unknown(args)
    if unknown is not None:
        return [unknown]
    arrays = [_arr(interp, a) if not isinstance(a, Str) else a for a in args]
    numbers = [a.numbers() if isinstance(a, Arr) else a for a in arrays]
    if any(v is None for v in numbers):
        raise Unsupported(f"`{name}` of values that depend on the time or the state is not translated")
    try:
        return [_NUMERIC[name](*numbers)]
    except (TypeError, ValueError, np.linalg.LinAlgError):
        raise Unsupported(f"`{name}` with these arguments is not translated") from None


def _vec(a: np.ndarray) -> np.ndarray:
    return a.reshape(-1) if (a.shape[0] == 1 or a.shape[1] == 1) else a


def _keep(a: np.ndarray, out: np.ndarray) -> Arr:
    out = np.asarray(out, dtype=float)
    if out.ndim == 1:
        return Arr.numeric(out.reshape(1, -1) if a.shape[0] == 1 else out.reshape(-1, 1))
    return Arr.numeric(out)


_NUMERIC = {
    "det": lambda a: Arr.numeric(np.linalg.det(a)), "trace": lambda a: Arr.numeric(np.trace(a)),
    "rank": lambda a: Arr.numeric(float(np.linalg.matrix_rank(a))), "cond": lambda a: Arr.numeric(np.linalg.cond(a)),
    "pinv": lambda a: Arr.numeric(np.linalg.pinv(a)), "kron": lambda a, b: Arr.numeric(np.kron(a, b)),
    "cumsum": lambda a: _keep(a, np.cumsum(_vec(a), axis=0)), "cumprod": lambda a: _keep(a, np.cumprod(_vec(a), axis=0)),
    "diff": lambda a: _keep(a, np.diff(_vec(a), axis=0)), "flipud": lambda a: Arr.numeric(a[::-1, :]),
    "fliplr": lambda a: Arr.numeric(a[:, ::-1]), "flip": lambda a: _keep(a, _vec(a)[::-1]),
    "sort": lambda a: _keep(a, np.sort(_vec(a), axis=0)), "unique": lambda a: _keep(a, np.unique(_vec(a))),
    "find": lambda a: _keep(a, np.flatnonzero(a.T.reshape(-1)) + 1.0),
    "any": lambda a: Arr.numeric(float(np.any(a != 0))), "all": lambda a: Arr.numeric(float(np.all(a != 0))),
    "trapz": lambda a, b=None: Arr.numeric(float(np.trapz(_vec(b), _vec(a)) if b is not None else np.trapz(_vec(a)))),
    "std": lambda a: Arr.numeric(float(np.std(_vec(a), ddof=1))), "var": lambda a: Arr.numeric(float(np.var(_vec(a), ddof=1))),
    "median": lambda a: Arr.numeric(float(np.median(_vec(a)))),
    "expm": lambda a: Arr.numeric(__import__("scipy.linalg", fromlist=["expm"]).expm(a)),
    "null": lambda a: Arr.numeric(__import__("scipy.linalg", fromlist=["null_space"]).null_space(a)),
}


# --- strings, structs, cells --------------------------------------------------------------------------


@builtin("strcmp", "strcmpi", "isequal")
def _strcmp(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    a, b = args[0], args[1]
    if isinstance(a, Unknown) or isinstance(b, Unknown):
        return [a if isinstance(a, Unknown) else b]
    if isinstance(a, Str) and isinstance(b, Str):
        same = a.text.lower() == b.text.lower() if name == "strcmpi" else a.text == b.text
        return [Arr.numeric(float(same))]
    if isinstance(a, Cell) and isinstance(b, Str):
        return [Arr.numeric([[float(isinstance(x, Str) and x.text == b.text) for x in a.items]])]
    if name == "isequal" and isinstance(a, Arr) and isinstance(b, Arr):
        x, y = a.numbers(), b.numbers()
        if x is None or y is None:
            raise Unsupported("isequal of values that depend on the state")
        return [Arr.numeric(float(x.shape == y.shape and bool(np.all(x == y))))]
    return [Arr.numeric(0.0)]


@builtin("lower", "upper", "strtrim", "char", "string")
def _strings(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    if not isinstance(args[0], Str):
        return [Unknown(f"`{name}` of a value that is not text", node.line, scope.file)]
    text = args[0].text
    return [Str({"lower": text.lower(), "upper": text.upper(), "strtrim": text.strip()}.get(name, text))]


@builtin("struct")
def _struct(interp, args, nargout, node, scope):
    if len(args) % 2:
        raise Unsupported("struct takes name-value pairs")
    fields = {}
    for name, value in zip(args[::2], args[1::2]):
        if not isinstance(name, Str):
            raise Unsupported("a struct's field name must be a constant string")
        if isinstance(value, Cell):
            if len(value.items) != 1:
                raise Unsupported("struct arrays (a cell of values in struct(...)) are not translated")
            value = value.items[0]
        fields[name.text] = value
    return [Struct(fields)]


@builtin("getfield")
def _getfield(interp, args, nargout, node, scope):
    from odelab.formats.matlab.evaluate import field_of

    if len(args) != 2 or not isinstance(args[1], Str):
        raise Unsupported("getfield(s, 'name') with a constant name")
    return [field_of(interp, args[0], args[1].text, node.line)]


@builtin("setfield")
def _setfield(interp, args, nargout, node, scope):
    if len(args) != 3 or not isinstance(args[0], Struct) or not isinstance(args[1], Str):
        raise Unsupported("setfield(s, 'name', value) with a constant name")
    return [Struct({**args[0].fields, args[1].text: args[2]}, origin=args[0].origin, odeset=args[0].odeset)]


@builtin("fieldnames")
def _fieldnames(interp, args, nargout, node, scope):
    if not isinstance(args[0], Struct):
        raise Unsupported("fieldnames of a value that is not a struct")
    names = [Str(k) for k in args[0].fields]
    return [Cell(len(names), 1, names)]


@builtin("cell")
def _cell(interp, args, nargout, node, scope):
    rows, cols = _dims(interp, args) if args else (0, 0)
    return [Cell(rows, cols, [Arr(0, 0, data=np.zeros((0, 0)))] * (rows * cols))]


@builtin("num2cell")
def _num2cell(interp, args, nargout, node, scope):
    a = _arr(interp, args[0])
    return [Cell(a.rows, a.cols, [Arr.scalar(x) for x in a.all_items()])]


@builtin("deal")
def _deal(interp, args, nargout, node, scope):
    if len(args) == 1:
        return [args[0]] * max(nargout, 1)
    return list(args)


@builtin("cell2mat")
def _cell2mat(interp, args, nargout, node, scope):
    cell = args[0]
    if not isinstance(cell, Cell):
        raise Unsupported("cell2mat of a value that is not a cell array")
    rows = [[_arr(interp, cell.items[j * cell.rows + i]) for j in range(cell.cols)] for i in range(cell.rows)]
    return [ops.concat(rows)]


# --- functions, errors, control ------------------------------------------------------------------------


@builtin("feval")
def _feval(interp, args, nargout, node, scope):
    if not args:
        raise Unsupported("feval needs a function")
    fn = args[0]
    if isinstance(fn, Str):
        fn = FuncValue(name=fn.text, file=scope.file, line=node.line)
    if not isinstance(fn, FuncValue):
        raise Unsupported("feval of a computed function name (write the function handle, @name)")
    return interp.call_value(fn, list(args[1:]), nargout, node.line, scope.mode)


@builtin("str2func")
def _str2func(interp, args, nargout, node, scope):
    if not args or not isinstance(args[0], Str):
        raise Unsupported("str2func of a computed name")
    text = args[0].text.strip()
    if text.startswith("@"):
        from odelab.formats.matlab.parser import parse_text

        parsed = parse_text(f"__f = {text};", scope.file)
        return [interp.eval(parsed.script[0].value, scope)]
    return [FuncValue(name=text, file=scope.file, line=node.line)]


@builtin("inline", "vectorize")
def _inline(interp, args, nargout, node, scope):
    """MATLAB 5's ``inline('expr', 't', 'y')``: the text read (parsed, never run) as an anonymous function."""
    name = node.target.name if isinstance(node, n.Index) else node.name
    if not args or not isinstance(args[0], Str):
        raise Unsupported(f"`{name}` of a value that is not constant text")
    if name == "vectorize":
        return [args[0]]
    from odelab.formats.matlab.lexer import tokenize
    from odelab.formats.matlab.parser import parse_text

    text = args[0].text
    names = [a.text for a in args[1:] if isinstance(a, Str)]
    if not names:  # MATLAB's rule: the variables of the text, in alphabetical order (x if there is none)
        known = set(BUILTINS) | {"i", "j"}
        found = sorted({t.text for t in tokenize(text, scope.file) if t.kind == "name" and t.text not in known})
        names = found or ["x"]
    parsed = parse_text(f"__inline = @({', '.join(names)}) {text};", scope.file)
    value = interp.eval(parsed.script[0].value, scope)
    value.text = f"inline('{text}')"
    value.line = node.line
    return [value]


@builtin("func2str")
def _func2str(interp, args, nargout, node, scope):
    fn = args[0]
    return [Str(fn.text or f"@{fn.name}")] if isinstance(fn, FuncValue) else [Unknown("func2str", node.line)]


@builtin("error")
def _error(interp, args, nargout, node, scope):
    from odelab.formats.matlab.flow import ErrorCalled

    message = args[0].text if args and isinstance(args[0], Str) else "error"
    raise ErrorCalled(message, node.line)


@builtin("odeset")
def _odeset(interp, args, nargout, node, scope):
    from odelab.formats.matlab.options import odeset

    return odeset(interp, args, nargout, node, scope)


@builtin("odeget")
def _odeget(interp, args, nargout, node, scope):
    from odelab.formats.matlab.options import odeget

    return odeget(interp, args, nargout, node, scope)


def _solver(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    if interp.on_solver is None or scope.mode != "script":
        raise Unsupported(f"`{name}` inside a right-hand side (a solver called by the equations) is not translated")
    return interp.on_solver(interp, name, args, nargout, node, scope)


for _name in SOLVERS:
    BUILTINS[_name] = _solver


def _unsupported_solver(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    what = UNSUPPORTED_SOLVERS[name]
    if scope.mode == "script":
        interp.note(node.line, f"{name}(...)", "gap", f"{what} ({name}) is not translated; odelab's own "
                    "experiment files may express it (docs: delays, stiff)", scope.file)
    return [Unknown(f"{name} is not translated", node.line, scope.file)] * max(nargout, 1)


for _name in UNSUPPORTED_SOLVERS:
    BUILTINS[_name] = _unsupported_solver


@builtin("decic")
def _decic(interp, args, nargout, node, scope):
    """``[y0, yp0] = decic(f, t0, y0, fixed_y0, yp0, fixed_yp0)``: odelab runs decic itself when it loads the
    implicit system; the call's fixed components become ``[initial.fixed]`` (the values pass through)."""
    if len(args) < 6:
        raise Unsupported("decic(f, t0, y0, fixed_y0, yp0, fixed_yp0) with all six arguments")
    flags = []
    for value in (args[3], args[5]):
        numbers = value.numbers() if isinstance(value, Arr) else None
        flags.append(None if numbers is None or numbers.size == 0 else [bool(v) for v in numbers.T.reshape(-1)])
    interp.decic_calls.append((args[0], flags[0], flags[1], node.line))
    if scope.mode == "script":
        interp.note(node.line, "decic(...)", "translated", "the fixed components as [initial.fixed]: odelab makes the "
                    "initial values consistent (MATLAB's decic) when it loads the file", scope.file)
    return [args[2], args[4]][:max(nargout, 1)]


@builtin("deval", "odextend")
def _deval(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    if scope.mode == "script":
        interp.note(node.line, f"{name}(...)", IGNORED, "evaluates a stored solution: odelab stores every case's "
                    "trajectory (its Python API has deval)", scope.file)
    return [Unknown(f"{name} evaluates a solution odelab stores instead", node.line, scope.file)] * max(nargout, 1)


@builtin("interp1")
def _interp1(interp, args, nargout, node, scope):
    from odelab.formats.matlab.tables import interp1

    return [interp1(interp, args, node, scope)]


@builtin("load", "readmatrix", "csvread", "dlmread", "importdata", "table2array")
def _load(interp, args, nargout, node, scope):
    from odelab.formats.matlab.tables import load

    return [load(interp, args, node, scope)]


# --- what odelab does not run ------------------------------------------------------------------------


def _refused(interp, args, nargout, node, scope):
    name = node.target.name if isinstance(node, n.Index) else node.name
    raise ExperimentError(f"line {node.line}: `{name}` {REFUSED[name]}; odelab reads MATLAB files without running "
                          "them and refuses a file that would run code or commands. Remove the call (or write the "
                          "experiment file by hand).", source=scope.file)


for _name in REFUSED:
    BUILTINS[_name] = _refused


def _ignored(kind: str):
    def handler(interp, args, nargout, node, scope):
        name = node.target.name if isinstance(node, n.Index) else node.name
        shown = f"{name}(...)" if isinstance(node, n.Index) else name
        if kind == "plotting":
            detail = "plotting: the report draws every state and output (odelab report)"
        elif kind == "printing":
            detail = "printing: odelab run prints the error tables and step statistics"
        else:
            detail = "has no effect on the experiment"
        interp.note(node.line, shown, IGNORED, detail, scope.file)
        return [Unknown(f"`{name}` is {kind}", node.line, scope.file)] * max(nargout, 1)
    return handler


for _name in PLOTTING:
    BUILTINS.setdefault(_name, _ignored("plotting"))
for _name in PRINTING:
    BUILTINS.setdefault(_name, _ignored("printing"))
for _name in IGNORED_CALLS:
    BUILTINS.setdefault(_name, _ignored("housekeeping"))


def _unknowable(reason: str):
    def handler(interp, args, nargout, node, scope):
        name = node.target.name if isinstance(node, n.Index) else node.name
        why = f"`{name}` {reason}"
        if scope.mode == "script":
            interp.note(node.line, f"{name}(...)" if isinstance(node, n.Index) else name, IGNORED, f"not run: {why}",
                        scope.file)
        return [Unknown(why, node.line, scope.file)] * max(nargout, 1)
    return handler


for _name in RANDOM:
    BUILTINS[_name] = _unknowable("draws random numbers (odelab cannot reproduce MATLAB's generator: write the "
                                  "values into the experiment file)")
for _name in FILE_IO:
    BUILTINS[_name] = _unknowable("reads or writes a file odelab does not read (write the data as a CSV table)")
for _name in SYMBOLIC:
    BUILTINS[_name] = _unknowable("is the Symbolic Math Toolbox (write the equations it derives)")
for _name in INTERACTIVE:
    BUILTINS[_name] = _unknowable("asks the user (write the value into the experiment file)")


def command(interp, stmt: n.Command, scope) -> None:
    """Command syntax (``hold on``, ``format long``, ``load data.txt``, ``syms x``)."""
    name = stmt.name
    if name in REFUSED:
        raise ExperimentError(f"line {stmt.line}: `{name}` {REFUSED[name]}; odelab reads MATLAB files without "
                              "running them and refuses a file that would run code or commands.", source=scope.file)
    if name in ("load",) and stmt.words:
        from odelab.formats.matlab.tables import load_command

        load_command(interp, stmt, scope)
        return
    if name in SYMBOLIC:
        for word in stmt.words:
            scope.set(word, Unknown("a symbolic variable (the Symbolic Math Toolbox)", stmt.line, scope.file),
                      interp.globals)
        interp.note(stmt.line, stmt.text, IGNORED, "the Symbolic Math Toolbox is not translated", scope.file)
        return
    if name in ("clear", "clearvars") and stmt.words and stmt.words[0] not in ("all", "variables", "-all"):
        for word in stmt.words:
            scope.vars.pop(word, None)
    interp.note(stmt.line, stmt.text, IGNORED, "a command with no effect on the experiment"
                if name not in PLOTTING else "plotting: the report draws every state and output", scope.file)
