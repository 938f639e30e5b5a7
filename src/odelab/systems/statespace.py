"""Linear time-invariant systems in state-space form, as Simulink's State-Space block.

    x' = A x + B u
    y  = C x + D u

:class:`StateSpace` holds the four matrices (read-only float arrays) and the names of the
states, inputs and outputs. It implements the system protocol every odelab system shares
(``dynamics(t, x, u)`` and ``output(t, x, u)``), so :func:`odelab.systems.simulate.simulate`
integrates it like any other system, and :func:`odelab.analysis.lti.lti_response` computes
its exact response.

How the matrices may be given
-----------------------------
Scalars, nested lists and numpy arrays. A 1-D ``B`` or ``C`` is accepted where it can only
mean one thing, and is read as follows (n states):

* ``B``, 1-D of length n: one **column**, i.e. one input (``B=[0, 1]`` is 2x1). For a
  one-state system (n = 1) a 1-D ``B`` of length m is one row: m inputs.
* ``C``, 1-D of length n: one **row**, i.e. one output (``C=[10, 0]`` is 1x2). For a
  one-state system a 1-D ``C`` of length p is one column: p outputs.
* ``D``, 1-D: a row when there is one output, a column when there is one input. A scalar
  ``D`` is 1x1; the scalar 0 is also accepted for any size (all zeros).

The number of inputs m is taken from ``inputs`` if given, else from B, else from D, else 0;
the number of outputs p from ``outputs`` if given, else from C, else p = n (C = identity).
"""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real
from typing import Any

import numpy as np

from odelab.exceptions import InputError

__all__ = ["StateSpace"]


def _count(n: int, noun: str) -> str:
    """'there is 1 input' / 'there are 2 inputs'."""
    return f"there {'is' if n == 1 else 'are'} {n} {noun}{'' if n == 1 else 's'}"


def _shape(M: np.ndarray) -> str:
    if M.ndim == 0:
        return "a scalar"
    if M.ndim == 1:
        return f"a 1-D array of length {M.shape[0]}"
    return "x".join(str(d) for d in M.shape)


def _as_array(value: Any, name: str) -> np.ndarray:
    """A finite real float array (any dimension, checked later), or InputError."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):  # ragged nested lists
        raw = None
    if raw is not None and raw.dtype.kind == "c":
        raise InputError(f"`{name}` must be real; got complex entries {value!r}.", key=name)
    if raw is not None and raw.dtype.kind == "O" and all(
        isinstance(v, Real) and not isinstance(v, bool) for v in raw.flat
    ):
        raw = raw.astype(float)  # e.g. fractions.Fraction entries
    if raw is None or raw.dtype.kind not in "iuf":
        raise InputError(
            f"`{name}` must be a matrix of real numbers (a number, a nested list or an "
            f"array); got {value!r}.",
            key=name,
        )
    M = raw.astype(float)
    if M.ndim > 2:
        raise InputError(f"`{name}` must be at most 2-D; got an array of shape {M.shape}.", key=name)
    bad = np.argwhere(~np.isfinite(M))
    if bad.size:
        where = f" at [{', '.join(str(int(i)) for i in bad[0])}]" if M.ndim else ""
        raise InputError(
            f"`{name}` must have finite entries; got {float(M[tuple(bad[0])])!r}{where}.", key=name
        )
    return M


def _names(value: Any, count: int, prefix: str, name: str, what: str) -> tuple[str, ...]:
    """Names of the states/inputs/outputs: default prefix1..prefixN, checked otherwise."""
    if value is None:
        return tuple(f"{prefix}{i + 1}" for i in range(count))
    names = _as_tuple(value)
    for item in names:
        if not isinstance(item, str) or not item.strip():
            raise InputError(f"`{name}` must be non-empty strings; got {item!r}.", key=name)
    if len(names) != count:
        raise InputError(
            f"`{name}` has {len(names)} name{'' if len(names) == 1 else 's'} but "
            f"{_count(count, what)}: give {count} name{'' if count == 1 else 's'}.",
            key=name,
        )
    seen: set[str] = set()
    for item in names:
        if item in seen:
            raise InputError(f"`{name}` must be unique; {item!r} appears twice.", key=name)
        seen.add(item)
    return names


def _as_tuple(names: Any) -> tuple:
    return (names,) if isinstance(names, str) else tuple(names)


def _readonly(M: np.ndarray) -> np.ndarray:
    M = np.array(M, dtype=float)  # a private copy: the caller's array may change later
    M.setflags(write=False)
    return M


class StateSpace:
    """A linear time-invariant system x' = Ax + Bu, y = Cx + Du.

    Parameters
    ----------
    A
        State matrix, n x n (n >= 1).
    B
        Input matrix, n x m. ``None``: no inputs (n x 0), unless ``inputs`` or ``D`` say
        how many there are, then zeros.
    C
        Output matrix, p x n. ``None``: the identity, and the outputs are the states (named
        after them unless ``outputs`` is given).
    D
        Feedthrough matrix, p x m. ``None``: zeros.
    states, inputs, outputs
        Names, unique within each list; default ``x1..xn``, ``u1..um``, ``y1..yp``. A single
        string is one name.
    operating_point
        Where the system was linearised (set by :func:`odelab.analysis.linearize.linearize`);
        stored as given, never inspected.

    See the module docstring for how 1-D and scalar matrices are read.

    Examples
    --------
    The lab's mass-spring-damper (m = 1, k = 3, b = 4) measured with gain q = 10:

    >>> plant = StateSpace([[0, 1], [-3, -4]], [0, 1], [10, 0], 0)
    >>> plant.B.shape, plant.C.shape, plant.D.shape
    ((2, 1), (1, 2), (1, 1))
    """

    __slots__ = ("_A", "_B", "_C", "_D", "_states", "_inputs", "_outputs", "_operating_point")

    def __init__(
        self,
        A: Any,
        B: Any = None,
        C: Any = None,
        D: Any = None,
        *,
        states: Sequence[str] | str | None = None,
        inputs: Sequence[str] | str | None = None,
        outputs: Sequence[str] | str | None = None,
        operating_point: Any = None,
    ):
        A = _as_array(A, "A")
        if A.ndim < 2:
            if A.size != 1:
                raise InputError(
                    f"`A` is {_shape(A)}: A must be square (n x n); pass a 2-D array.", key="A"
                )
            A = A.reshape(1, 1)
        n = A.shape[0]
        if A.shape[0] != A.shape[1]:
            raise InputError(f"`A` is {_shape(A)}: A must be square (n x n).", key="A")
        if n == 0:
            raise InputError("`A` is 0x0: a state-space system needs at least one state.", key="A")

        Bm = None if B is None else _as_array(B, "B")
        Cm = None if C is None else _as_array(C, "C")
        Dm = None if D is None else _as_array(D, "D")

        # Read 1-D B and C (see the module docstring): B is a column, C a row, except for a
        # one-state system where that reading could not hold more than one input/output.
        if Bm is not None and Bm.ndim < 2:
            if Bm.ndim == 0 or n == 1:
                Bm = Bm.reshape(1, -1) if n == 1 else Bm.reshape(1, 1)
            elif Bm.shape[0] == n:
                Bm = Bm.reshape(n, 1)
            else:
                raise InputError(
                    f"`B` is {_shape(Bm)} but A is {n}x{n}: a 1-D B is read as one column "
                    f"(one input), so it must have length {n}; pass a 2-D array for several "
                    "inputs.",
                    key="B",
                )
        if Cm is not None and Cm.ndim < 2:
            if Cm.ndim == 0 or n == 1:
                Cm = Cm.reshape(-1, 1) if n == 1 else Cm.reshape(1, 1)
            elif Cm.shape[0] == n:
                Cm = Cm.reshape(1, n)
            else:
                raise InputError(
                    f"`C` is {_shape(Cm)} but A is {n}x{n}: a 1-D C is read as one row "
                    f"(one output), so it must have length {n}; pass a 2-D array for several "
                    "outputs.",
                    key="C",
                )

        # Number of outputs p and inputs m: the names win, then the matrices.
        n_outputs = None if outputs is None else len(_as_tuple(outputs))
        if Cm is not None:
            p = Cm.shape[0] if n_outputs is None else n_outputs
        else:
            p = n
            if n_outputs is not None and n_outputs != n:
                count = n_outputs
                raise InputError(
                    f"`outputs` has {count} name{'' if count == 1 else 's'} but C is not given, "
                    f"so the outputs are the {n} state{'' if n == 1 else 's'}: give C, or "
                    f"{n} output name{'' if n == 1 else 's'}.",
                    key="outputs",
                )
        if inputs is not None:
            m = len(_as_tuple(inputs))
        elif Bm is not None:
            m = Bm.shape[1]
        elif Dm is not None and Dm.ndim == 2:
            m = Dm.shape[1]
        elif Dm is not None and Dm.ndim == 1:
            m = Dm.shape[0] if p == 1 else 1  # a row for one output, else a column
        elif Dm is not None and Dm != 0:
            m = 1
        else:
            m = 0

        if Bm is None:
            Bm = np.zeros((n, m))
        if Bm.shape != (n, m):
            raise InputError(
                f"`B` is {_shape(Bm)} but A is {n}x{n} and {_count(m, 'input')}: "
                f"B must be {n}x{m}",
                key="B",
            )
        if Cm is None:
            Cm = np.eye(n)
        if Cm.shape != (p, n):
            raise InputError(
                f"`C` is {_shape(Cm)} but A is {n}x{n} and {_count(p, 'output')}: "
                f"C must be {p}x{n}",
                key="C",
            )
        if Dm is None:
            Dm = np.zeros((p, m))
        elif Dm.ndim == 0:
            if Dm == 0:
                Dm = np.zeros((p, m))
            elif (p, m) == (1, 1):
                Dm = Dm.reshape(1, 1)
            else:
                raise InputError(
                    f"`D` is the scalar {float(Dm)!r} but {_count(p, 'output')} and "
                    f"{m} input{'' if m == 1 else 's'}: D must be {p}x{m} (a scalar D is "
                    "accepted for one input and one output, or when it is 0).",
                    key="D",
                )
        elif Dm.ndim == 1:
            if p == 1 and Dm.shape[0] == m:
                Dm = Dm.reshape(1, m)
            elif m == 1 and Dm.shape[0] == p:
                Dm = Dm.reshape(p, 1)
            else:
                raise InputError(
                    f"`D` is {_shape(Dm)} but {_count(p, 'output')} and "
                    f"{m} input{'' if m == 1 else 's'}: D must be {p}x{m}",
                    key="D",
                )
        if Dm.shape != (p, m):
            raise InputError(
                f"`D` is {_shape(Dm)} but {_count(p, 'output')} and "
                f"{m} input{'' if m == 1 else 's'}: D must be {p}x{m}",
                key="D",
            )

        self._A = _readonly(A)
        self._B = _readonly(Bm)
        self._C = _readonly(Cm)
        self._D = _readonly(Dm)
        self._states = _names(states, n, "x", "states", "state")
        self._inputs = _names(inputs, m, "u", "inputs", "input")
        if outputs is None and C is None:
            self._outputs = self._states
        else:
            self._outputs = _names(outputs, p, "y", "outputs", "output")
        self._operating_point = operating_point

    # -- read-only attributes -------------------------------------------------------------

    @property
    def A(self) -> np.ndarray:
        """State matrix, n x n (read-only)."""
        return self._A

    @property
    def B(self) -> np.ndarray:
        """Input matrix, n x m (read-only)."""
        return self._B

    @property
    def C(self) -> np.ndarray:
        """Output matrix, p x n (read-only)."""
        return self._C

    @property
    def D(self) -> np.ndarray:
        """Feedthrough matrix, p x m (read-only)."""
        return self._D

    @property
    def nx(self) -> int:
        """Number of states n."""
        return self._A.shape[0]

    @property
    def nu(self) -> int:
        """Number of inputs m."""
        return self._B.shape[1]

    @property
    def ny(self) -> int:
        """Number of outputs p."""
        return self._C.shape[0]

    @property
    def states(self) -> tuple[str, ...]:
        return self._states

    @property
    def inputs(self) -> tuple[str, ...]:
        return self._inputs

    @property
    def outputs(self) -> tuple[str, ...]:
        return self._outputs

    @property
    def operating_point(self) -> Any:
        """Where the system was linearised, as :func:`linearize` stored it (or None)."""
        return self._operating_point

    def __setattr__(self, name: str, value: Any) -> None:
        if hasattr(self, "_operating_point"):  # fully built: immutable from now on
            raise AttributeError(f"StateSpace is immutable; cannot set {name!r}.")
        object.__setattr__(self, name, value)

    # -- the system protocol --------------------------------------------------------------

    def dynamics(self, t: float, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """x' = A x + B u, shape (nx,). ``t`` is unused (the system is time-invariant)."""
        dx = self._A @ x
        if self._B.shape[1]:
            dx = dx + self._B @ np.asarray(u, dtype=float)
        return dx

    def output(self, t: float, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """y = C x + D u, shape (ny,)."""
        y = self._C @ x
        if self._D.shape[1]:
            y = y + self._D @ np.asarray(u, dtype=float)
        return y

    # -- comparison and display -----------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        """Same matrices (exactly) and same names; the operating point is not compared."""
        if not isinstance(other, StateSpace):
            return NotImplemented
        return (
            self.names() == other.names()
            and all(np.array_equal(a, b) for a, b in zip(self.matrices(), other.matrices()))
        )

    __hash__ = None  # mutable-looking arrays inside: equality, not identity, matters

    def allclose(self, other: StateSpace, *, rtol: float = 1e-12, atol: float = 1e-12) -> bool:
        """Same shapes and matrices equal within ``numpy.allclose(rtol, atol)``; names ignored."""
        if not isinstance(other, StateSpace):
            raise InputError(f"`other` must be a StateSpace; got {type(other).__name__}.", key="other")
        return all(
            a.shape == b.shape and np.allclose(a, b, rtol=rtol, atol=atol)
            for a, b in zip(self.matrices(), other.matrices())
        )

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B, C, D)``."""
        return self._A, self._B, self._C, self._D

    def names(self) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
        """``(states, inputs, outputs)``."""
        return self._states, self._inputs, self._outputs

    def __repr__(self) -> str:
        lines = ["StateSpace("]
        for name, M in zip("ABCD", self.matrices()):
            prefix = f"    {name}="
            if M.size == 0:
                text = f"np.zeros(({M.shape[0]}, {M.shape[1]}))"
            else:
                text = np.array2string(M, separator=", ", prefix=prefix)
            lines.append(f"{prefix}{text},")
        lines.append(f"    states={self._states!r}, inputs={self._inputs!r}, outputs={self._outputs!r},")
        if self._operating_point is not None:
            lines.append(f"    operating_point={self._operating_point!r},")
        lines.append(")")
        return "\n".join(lines)

