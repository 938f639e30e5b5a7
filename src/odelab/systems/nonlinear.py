"""Nonlinear systems x' = f(t, x, u), y = h(t, x, u), from Python functions or expressions.

A :class:`NonlinearSystem` follows the same protocol as
:class:`~odelab.systems.statespace.StateSpace` (``nx, nu, ny, states, inputs, outputs``,
``dynamics(t, x, u)``, ``output(t, x, u)``), so :func:`~odelab.systems.simulate.simulate`
and :mod:`odelab.analysis.linearize` take either.

Two ways to build one::

    # from Python functions
    def f(t, x, u):
        return np.array([x[1], (u[0] - 4 * x[1] - 3 * x[0] - x[0] ** 3) / 1.0])
    spring = NonlinearSystem(f, states=["x", "v"], inputs=["f"])

    # from the expressions of an experiment file
    spring = NonlinearSystem.from_expressions(
        {"x": "v", "v": "(f - b*v - k1*x - k3*x^3) / m"},
        inputs=["f"], parameters={"m": 1, "b": 4, "k1": 3, "k3": 1},
    )

A system built from expressions also keeps a variant of its functions that is safe for
complex-step differentiation (Squire & Trapp, SIAM Review 40(1), 1998), which
:func:`~odelab.analysis.linearize.jacobians` uses to get Jacobians to machine precision.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from odelab.exceptions import InputError

__all__ = ["NonlinearSystem", "as_vector", "validate_names"]

Vectorfield = Callable[[float, np.ndarray, np.ndarray], Any]

_EMPTY = np.zeros(0)
_EMPTY.setflags(write=False)


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _describe(names: Sequence[str], word: str) -> str:
    """'2 states (x, v)', '1 input (f)', 'no outputs'."""
    if not names:
        return f"no {word}s"
    return f"{_plural(len(names), word)} ({', '.join(names)})"


def validate_names(names, what: str, *, source: str | None = None) -> tuple[str, ...]:
    """Return ``names`` as a tuple of non-empty, unique strings, or raise InputError.

    A single string is one name (``"x"`` -> ``("x",)``). ``what`` is the argument's name,
    used in the message (``states``, ``inputs``...).
    """
    if names is None:
        return ()
    if isinstance(names, str):
        names = (names,)
    try:
        names = tuple(names)
    except TypeError:
        raise InputError(
            f"`{what}` must be a sequence of names; got {names!r}.", source=source, key=what
        ) from None
    seen: set[str] = set()
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name.strip():
            raise InputError(
                f"`{what}[{i}]` must be a non-empty string; got {name!r}.",
                source=source,
                key=what,
            )
        if name in seen:
            raise InputError(
                f"`{what}` names {name!r} twice; each name must be unique. Got {list(names)}.",
                source=source,
                key=what,
            )
        seen.add(name)
    return names


class NonlinearSystem:
    """A nonlinear system x' = f(t, x, u), y = h(t, x, u).

    Parameters
    ----------
    dynamics
        ``dynamics(t, x, u)`` returns x' as nx numbers; ``x`` has shape (nx,) and ``u``
        shape (nu,) (empty when the system has no inputs).
    output
        ``output(t, x, u)`` returns y as ny numbers. Default: y = x.
    states, inputs, outputs
        Names, non-empty and unique. ``outputs`` defaults to ``states`` when ``output`` is
        not given, and must be given when it is. A state and an input may not share a name;
        an output may share a state's name (as the default y = x does).
    name
        Shown in reports and messages.
    complex_step
        Whether ``dynamics`` and ``output`` accept complex ``x`` and ``u`` and are analytic
        (no ``abs``, ``real``, comparisons...), so complex-step differentiation is exact:
        ``True`` trusts them, ``False`` never tries, ``None`` (default) lets
        :func:`~odelab.analysis.linearize.jacobians` try and check against a finite
        difference.

    Notes
    -----
    The shapes the functions return are checked on every call (a cheap ``shape``
    comparison): a column vector of the right size is flattened, anything else raises an
    :class:`~odelab.exceptions.InputError` naming the function and the state names.
    :meth:`check` evaluates both functions once at a point and also rejects non-finite values.
    """

    def __init__(
        self,
        dynamics: Vectorfield,
        output: Vectorfield | None = None,
        *,
        states: Sequence[str],
        inputs: Sequence[str] = (),
        outputs: Sequence[str] | None = None,
        name: str = "",
        complex_step: bool | None = None,
        source: str | None = None,
    ):
        if not callable(dynamics):
            raise InputError(f"`dynamics` must be callable as dynamics(t, x, u); got {dynamics!r}.")
        if output is not None and not callable(output):
            raise InputError(f"`output` must be callable as output(t, x, u) or None; got {output!r}.")
        self.states = validate_names(states, "states", source=source)
        if not self.states and output is None:  # a static system (y = g(t, u): a diagram of gains) has none
            raise InputError("`states` must name at least one state.", source=source, key="states")
        self.inputs = validate_names(inputs, "inputs", source=source)
        clash = sorted(set(self.states) & set(self.inputs))
        if clash:
            raise InputError(
                f"{', '.join(map(repr, clash))} is both a state and an input; rename one.",
                source=source,
                key="inputs",
            )
        if output is None:
            if outputs is not None and validate_names(outputs, "outputs") != self.states:
                raise InputError(
                    "`outputs` can only be the state names when no `output` function is given "
                    f"(y = x); got {list(outputs)} for {_describe(self.states, 'state')}.",
                    source=source,
                    key="outputs",
                )
            self.outputs = self.states
        else:
            if outputs is None:
                raise InputError(
                    "`outputs` must name the outputs when an `output` function is given.",
                    source=source,
                    key="outputs",
                )
            self.outputs = validate_names(outputs, "outputs", source=source)
        self.name = str(name)
        self.complex_step = complex_step
        self._dynamics = dynamics
        self._output = output
        # Set by from_expressions: variants safe for complex-step differentiation, and the
        # texts they were compiled from (for reports).
        self.complex_step_dynamics: Vectorfield | None = None
        self.complex_step_output: Vectorfield | None = None
        self.equations: dict[str, str] | None = None
        self.output_equations: dict[str, str] | None = None
        self.parameters: dict[str, float] | None = None
        self.source = source

    # -- the protocol -------------------------------------------------------------------

    @property
    def nx(self) -> int:
        return len(self.states)

    @property
    def nu(self) -> int:
        return len(self.inputs)

    @property
    def ny(self) -> int:
        return len(self.outputs)

    def dynamics(self, t: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """x' at time ``t``, state ``x`` and input ``u``, shape (nx,)."""
        if u is None:
            u = _EMPTY
        return self._shaped(self._dynamics(t, x, u), "dynamics", self.states, "state")

    def output(self, t: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """y at time ``t``, state ``x`` and input ``u``, shape (ny,)."""
        if self._output is None:
            return np.array(x, copy=True).reshape(self.nx)
        if u is None:
            u = _EMPTY
        return self._shaped(self._output(t, x, u), "output", self.outputs, "output")

    @property
    def has_output_function(self) -> bool:
        """False when y = x."""
        return self._output is not None

    def _shaped(self, value, function: str, names: tuple[str, ...], word: str) -> np.ndarray:
        try:
            out = np.asarray(value)
        except ValueError:  # ragged sequence
            out = np.asarray(value, dtype=object)
        n = len(names)
        if out.shape != (n,):
            if out.size != n or out.dtype == object:
                shape = f" (shape {out.shape})" if out.ndim != 1 else ""
                raise InputError(
                    f"`{function}` returned {_plural(out.size, 'value')}{shape} "
                    f"but the system has {_describe(names, word)}.",
                    source=self.source,
                    key=function,
                )
            out = out.reshape(n)
        return out

    # -- checks -------------------------------------------------------------------------

    def vector(self, value, names: Sequence[str], what: str, word: str = "value") -> np.ndarray:
        """``value`` (scalar for one name, sequence, or mapping name -> number) as an array."""
        return as_vector(value, names, what, word=word, source=self.source)

    def check(self, x0, u0=None, t: float = 0.0) -> None:
        """Evaluate ``dynamics`` and ``output`` once at (t, x0, u0) and check what they return.

        Raises
        ------
        InputError
            When ``x0`` or ``u0`` has the wrong size, or a function returns the wrong number
            of values or a value that is not finite.
        """
        x = self.vector(x0, self.states, "x0", "state")
        u = self.vector(np.zeros(self.nu) if u0 is None else u0, self.inputs, "u0", "input")
        for function, value, names in (
            ("dynamics", self.dynamics(t, x, u), self.states),
            ("output", self.output(t, x, u), self.outputs),
        ):
            bad = [name for name, v in zip(names, value) if not np.isfinite(v)]
            if bad:
                raise InputError(
                    f"`{function}` is not finite for {', '.join(bad)} at t = {t:g}, "
                    f"x = {x.tolist()}, u = {u.tolist()}; check the model and the point.",
                    source=self.source,
                    key=function,
                )

    # -- construction from expressions --------------------------------------------------

    @classmethod
    def from_expressions(
        cls,
        equations: Mapping[str, str],
        *,
        inputs: Sequence[str] = (),
        outputs: Mapping[str, str] | None = None,
        parameters: Mapping[str, float] | None = None,
        name: str = "",
        source: str | None = None,
    ) -> "NonlinearSystem":
        """A system whose x' and y are expressions of the safe expression language.

        Parameters
        ----------
        equations
            State name -> expression of x' (in ``t``, the states, the inputs and the
            parameters). The mapping's order is the order of the states.
        inputs
            Input names.
        outputs
            Output name -> expression of y. Default: y = x.
        parameters
            Constants the expressions may use, e.g. ``{"m": 1.0, "b": 4.0}``.
        source
            The experiment file, for messages. Errors are located at the key paths
            ``system.equations.<state>`` and ``system.outputs.<name>``.
        """
        from odelab.expressions import compile_vector

        if not isinstance(equations, Mapping) or not equations:
            raise InputError(
                "`system.equations` must map each state name to the expression of its "
                f"derivative, e.g. {{'x': 'v', 'v': '-k*x'}}; got {equations!r}.",
                source=source,
                key="system.equations",
            )
        states = validate_names(list(equations), "states", source=source)
        inputs = validate_names(inputs, "inputs", source=source)
        parameters = dict(parameters or {})
        for pname, value in parameters.items():
            if pname in states or pname in inputs or pname == "t":
                what = "a state" if pname in states else "an input" if pname in inputs else "time"
                raise InputError(
                    f"parameter {pname!r} has the name of {what}; rename it.",
                    source=source,
                    key=f"system.parameters.{pname}",
                )
            try:
                parameters[pname] = float(value)
            except (TypeError, ValueError):
                raise InputError(
                    f"parameter {pname!r} must be a number; got {value!r}.",
                    source=source,
                    key=f"system.parameters.{pname}",
                ) from None
        for n in (*states, *inputs):
            if n == "t":
                raise InputError(
                    "`t` is time in expressions; a state or input cannot be named `t`.",
                    source=source,
                    key="system.equations" if n in states else "system.inputs",
                )
        args = ["t", *states, *inputs]
        texts = [str(equations[s]) for s in states]
        keys = [f"system.equations.{s}" for s in states]
        f_real = compile_vector(texts, args=args, constants=parameters, keys=keys, source=source)
        f_cplx = compile_vector(
            texts, args=args, constants=parameters, keys=keys, source=source, complex_step=True
        )
        nx = len(states)

        def make(F):
            from odelab.systems.fields import InputField

            return InputField(F, nx)

        if outputs is None:
            h_real = h_cplx = None
            out_names = None
        else:
            if not isinstance(outputs, Mapping) or not outputs:
                raise InputError(
                    "`system.outputs` must map each output name to an expression, "
                    f"e.g. {{'y': '10*x'}}; got {outputs!r}.",
                    source=source,
                    key="system.outputs",
                )
            out_names = validate_names(list(outputs), "outputs", source=source)
            out_texts = [str(outputs[n]) for n in out_names]
            out_keys = [f"system.outputs.{n}" for n in out_names]
            g_real = compile_vector(out_texts, args=args, constants=parameters, keys=out_keys, source=source)
            g_cplx = compile_vector(
                out_texts, args=args, constants=parameters, keys=out_keys, source=source, complex_step=True
            )
            h_real, h_cplx = make(g_real), make(g_cplx)

        system = cls(
            make(f_real),
            h_real,
            states=states,
            inputs=inputs,
            outputs=out_names,
            name=name,
            complex_step=False,  # the plain functions are not used for complex step
            source=source,
        )
        system.complex_step_dynamics = make(f_cplx)
        system.complex_step_output = h_cplx
        system.equations = {s: str(equations[s]) for s in states}
        system.output_equations = None if outputs is None else {n: str(outputs[n]) for n in out_names}
        system.parameters = parameters
        return system

    def expression_parts(self):
        """``(F, G, F_complex)``: the functions :meth:`from_expressions` compiled, ``F(t, *x, *u)`` and
        ``G(t, *x, *u)`` (None without outputs) and F's complex-step twin, for the builders that hand
        the same right-hand side on as a case's ``fun`` and outputs without compiling the texts again."""
        from odelab.systems.fields import InputField

        if not isinstance(self._dynamics, InputField) or not isinstance(self.complex_step_dynamics, InputField):
            raise TypeError("expression_parts() is for a system made by NonlinearSystem.from_expressions")
        return self._dynamics.F, None if self._output is None else self._output.F, self.complex_step_dynamics.F

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return (
            f"NonlinearSystem({label}states={list(self.states)}, inputs={list(self.inputs)}, "
            f"outputs={list(self.outputs)})"
        )


def as_vector(
    value, names: Sequence[str], what: str, *, word: str = "value", source: str | None = None
) -> np.ndarray:
    """``value`` as a float array with one entry per name, or raise InputError.

    Accepts a scalar (only when there is exactly one name), a sequence of the right length,
    or a mapping name -> number that covers every name. ``what`` is the argument's name and
    ``word`` what the names are (``state``, ``input``), both for the message.
    """
    names = tuple(names)
    n = len(names)
    if isinstance(value, Mapping):
        unknown = [k for k in value if k not in names]
        missing = [k for k in names if k not in value]
        if unknown or missing:
            detail = f"unknown {unknown}" if unknown else f"missing {missing}"
            raise InputError(
                f"`{what}` must give a value for each of the {_describe(names, word)}; {detail}.",
                source=source,
                key=what,
            )
        value = [value[k] for k in names]
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"`{what}` must be numbers; got {value!r}.", source=source, key=what) from None
    if arr.ndim == 0 and n == 1:
        arr = arr.reshape(1)
    if arr.shape != (n,):
        if arr.size == n:
            arr = arr.reshape(n)
        else:
            raise InputError(
                f"`{what}` has {_plural(arr.size, 'value')} but the system has {_describe(names, word)}.",
                source=source,
                key=what,
            )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"`{what}` must be finite; got {arr.tolist()}.", source=source, key=what)
    return arr
