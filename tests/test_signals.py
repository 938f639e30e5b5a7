"""Input signals: values, breakpoints, exact forms, tables from CSV, arithmetic, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from odelab.exceptions import InputError
from odelab.signals import (
    Constant,
    ExactForm,
    Function,
    Piece,
    Pulse,
    Ramp,
    Scaled,
    Signal,
    Sine,
    Step,
    Sum,
    Table,
    Term,
    Terms,
    as_signal,
    as_signals,
)

T = np.linspace(-2.0, 7.0, 1801)  # a grid through every breakpoint used below (step 0.005)

EXAMPLES = {
    "step": Step(1.0, 0.5, 2.0),
    "unit step": Step(),
    "ramp": Ramp(2.0, 1.0, -1.0),
    "sine": Sine(2.0, 3.0, 0.4, 1.0),
    "negative frequency": Sine(1.5, -2.0, 1.0),
    "pulse": Pulse(1.5, 1.0, 0.3, 0.25),
    "table": Table([0.0, 1.0, 2.0, 4.0], [0.0, 1.0, 1.0, 3.0]),
    "constant": Constant(3.0),
    "terms": Terms(
        (Term(2.0, rate=-0.5), Term(1.0, 1.0, power=2, rate=0.1, freq=2.0, kind="sin")), start=0.5
    ),
    "sum": Step(1.0) + 2 * Ramp(start=2.0) - Sine(frequency=-2.0, phase=1.0),
    "empty sum": Sum(()),
    "pulse plus table": 3 * Pulse(period=0.7, delay=1.0) + Table([0.0, 2.0], [1.0, 0.0]),
}


def scale(values) -> float:
    return max(1.0, float(np.max(np.abs(values))))


# -- values ------------------------------------------------------------------------------


class TestValues:
    def test_scalar_in_float_out_and_shape_kept(self):
        assert Step()(0.0) == 1.0 and type(Step()(0.0)) is float
        assert Step()(-1e-300) == 0.0
        grid = np.array([[-1.0, 0.0], [2.0, -3.0]])
        out = Ramp()(grid)
        assert out.shape == (2, 2)
        np.testing.assert_array_equal(out, [[0.0, 0.0], [2.0, 0.0]])
        assert Constant(2.5)(np.zeros(4)).tolist() == [2.5] * 4

    def test_step_switches_at_its_time(self):
        u = Step(time=1.0, initial=-1.0, final=3.0)
        assert u(np.nextafter(1.0, 0.0)) == -1.0
        assert u(1.0) == 3.0  # Simulink: the final value at the step time
        assert Step().time == 0.0  # odelab's unit step; Simulink's block defaults to 1

    def test_ramp(self):
        u = Ramp(slope=2.0, start=1.0, initial=-1.0)
        np.testing.assert_array_equal(u(np.array([0.0, 1.0, 1.5, 4.0])), [-1.0, -1.0, 0.0, 5.0])

    def test_sine_in_rad_per_second(self):
        u = Sine(amplitude=2.0, frequency=3.0, phase=0.4, bias=1.0)
        t = np.array([0.0, 0.7, 2.0])
        np.testing.assert_array_equal(u(t), 1.0 + 2.0 * np.sin(3.0 * t + 0.4))

    def test_pulse_as_simulink_time_mode(self):
        u = Pulse(amplitude=2.0, period=1.0, width=0.25, delay=0.5)
        t = np.array([0.0, 0.49, 0.5, 0.7, 0.75, 0.99, 1.5, 1.74, 1.75, 10.5])
        np.testing.assert_array_equal(u(t), [0, 0, 2, 2, 0, 0, 2, 2, 0, 2])

    def test_pulse_edges_classified_to_the_last_bit(self):
        # period 0.1 is not a binary fraction: the edges are rounded, and __call__ must
        # switch exactly at the breakpoints it reports, over thousands of periods.
        u = Pulse(amplitude=1.0, period=0.1, width=0.3, delay=0.3)
        edges = u.breakpoints(0.0, 200.0)
        assert edges.size == 2 * 1997
        before = u(np.nextafter(edges, -np.inf))
        after = u(edges)
        np.testing.assert_array_equal(before, np.tile([0.0, 1.0], 1997))
        np.testing.assert_array_equal(after, np.tile([1.0, 0.0], 1997))

    def test_table_interpolates_and_holds(self):
        u = Table([0.0, 1.0, 3.0], [1.0, 3.0, 2.0])
        np.testing.assert_array_equal(u(np.array([-5.0, 0.0, 0.5, 1.0, 2.0, 3.0, 9.0])),
                                      [1.0, 1.0, 2.0, 3.0, 2.5, 2.0, 2.0])

    def test_function_vectorised_or_pointwise(self):
        assert Function(np.sin)(1.0) == math.sin(1.0)
        np.testing.assert_array_equal(Function(math.sin)(np.array([0.0, 1.0])), [0.0, math.sin(1.0)])
        np.testing.assert_array_equal(Function(lambda t: 2.0)(np.arange(3.0)), [2.0, 2.0, 2.0])
        assert repr(Function(np.cos, label="cos(t)")) == "Function('cos(t)')"

    def test_terms(self):
        u = Terms((Term(2.0, rate=-0.5), Term(1.0, tau=1.0, power=2)), start=0.0)
        t = np.array([-1.0, 0.0, 2.0])
        np.testing.assert_allclose(u(t), [0.0, 2.0 + 1.0, 2.0 * math.exp(-1.0) + 1.0], rtol=1e-15)

    def test_term_formula(self):
        term = Term(3.0, tau=0.5, power=2, rate=-0.7, freq=2.0, kind="sin")
        t = 1.75
        s = t - 0.5
        assert term(t) == pytest.approx(3.0 * s**2 * math.exp(-0.7 * s) * math.sin(2.0 * s), rel=1e-15)
        assert Term(1.0, freq=0.0, kind="sin")(2.0) == 0.0


# -- arithmetic --------------------------------------------------------------------------


class TestArithmetic:
    def test_operators_build_sums_and_scalings(self):
        u = 2 * Step() + 1 - Ramp() / 4
        assert isinstance(u, Sum)
        assert all(isinstance(term, Signal) for term in u.terms)
        assert len(u.terms) == 3  # nested sums are flattened
        t = np.array([-1.0, 0.0, 2.0])
        np.testing.assert_array_equal(u(t), [1.0, 3.0, 2.5])
        np.testing.assert_array_equal((1 - Step())(t), [1.0, 0.0, 0.0])
        np.testing.assert_array_equal((-Step())(t), [0.0, -1.0, -1.0])
        assert Scaled(2.0, 3.0)(5.0) == 6.0  # a number is a Constant

    def test_product_of_signals_is_not_defined(self):
        with pytest.raises(TypeError):
            Step() * Ramp()

    def test_equality_and_hash(self):
        assert Step(1.0) == Step(1) and hash(Step(1.0)) == hash(Step(1))
        assert Table([0, 1], [2, 3]) == Table([0.0, 1.0], [2.0, 3.0])
        assert Table([0, 1], [2, 3]) != Table([0, 1], [2, 4])
        assert len({Step(1.0) + 1, Step(1.0) + 1}) == 1


# -- breakpoints -------------------------------------------------------------------------


class TestBreakpoints:
    def test_strictly_inside_either_direction(self):
        u = Step(1.0)
        assert u.breakpoints(0.0, 2.0).tolist() == [1.0]
        assert u.breakpoints(2.0, 0.0).tolist() == [1.0]
        assert u.breakpoints(1.0, 2.0).size == 0  # an end of the interval is not inside
        assert u.breakpoints(-1.0, 1.0).size == 0

    def test_each_kind(self):
        assert Ramp(start=2.0).breakpoints(0, 5).tolist() == [2.0]
        assert Ramp(slope=0.0, start=2.0).breakpoints(0, 5).size == 0  # no kink
        assert Step(1.0, 2.0, 2.0).breakpoints(0, 5).size == 0  # no jump
        assert Sine().breakpoints(0, 5).size == 0
        assert Constant(1.0).breakpoints(0, 5).size == 0
        assert Function(np.sin).breakpoints(0, 5).size == 0  # unknown to odelab
        assert Terms((Term(1.0),), start=1.5).breakpoints(0, 5).tolist() == [1.5]
        assert Pulse(1.0, 2.0, 0.25, 1.0).breakpoints(0.0, 5.5).tolist() == [1.0, 1.5, 3.0, 3.5, 5.0]
        assert Pulse(0.0, 2.0, 0.25, 1.0).breakpoints(0.0, 5.5).size == 0
        assert (Step(3.0) + Ramp(start=1.0) + Step(3.0, final=2.0)).breakpoints(5, 0).tolist() == [1.0, 3.0]

    def test_table_breakpoints_are_the_kinks(self):
        # collinear middle sample (t = 1) is no kink; the ends are (slope 0 outside)
        u = Table([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 1.0, 2.0, 2.0, 2.0])
        assert u.breakpoints(-1.0, 5.0).tolist() == [0.0, 2.0]
        flat_start = Table([0.0, 1.0, 2.0], [1.0, 1.0, 3.0])
        assert flat_start.breakpoints(-1.0, 5.0).tolist() == [1.0, 2.0]

    def test_too_many_pulse_edges_is_refused(self):
        with pytest.raises(InputError, match="edges"):
            Pulse(period=1e-6).breakpoints(0.0, 1e3)
        with pytest.raises(InputError, match="infinitely many"):
            Pulse().exact_terms().pieces(0.0, math.inf)


# -- exact forms -------------------------------------------------------------------------


class TestExactTerms:
    @pytest.mark.parametrize("name", list(EXAMPLES))
    def test_round_trip_on_a_grid_through_the_breakpoints(self, name):
        u = EXAMPLES[name]
        form = u.exact_terms()
        assert isinstance(form, ExactForm)
        expected = u(T)
        np.testing.assert_allclose(form(T), expected, rtol=0, atol=4e-15 * scale(expected))
        # and at every breakpoint itself, and just below it (right-continuity)
        bps = u.breakpoints(T[0], T[-1])
        for times in (bps, np.nextafter(bps, -np.inf)):
            np.testing.assert_allclose(form(times), u(times), rtol=0, atol=4e-15 * scale(expected))

    @pytest.mark.parametrize("name", list(EXAMPLES))
    def test_pieces_partition_the_window_at_the_breakpoints(self, name):
        u = EXAMPLES[name]
        pieces = u.exact_terms().pieces(-1.0, 6.0)
        assert pieces[0].start == -1.0 and pieces[-1].stop == 6.0
        for left, right in zip(pieces[:-1], pieces[1:]):
            assert left.stop == right.start
        starts = np.array([p.start for p in pieces[1:]])
        # every breakpoint starts a piece (a piece may start where nothing jumps, e.g. a
        # Table's collinear sample or a Step with initial == final)
        assert set(u.breakpoints(-1.0, 6.0)) <= set(starts)
        for piece in pieces:
            mid = 0.5 * (piece.start + piece.stop)
            assert piece(mid) == pytest.approx(u(mid), abs=1e-14 * scale(u(T)))

    def test_pieces_reversed_window_and_single_point(self):
        form = Step(1.0).exact_terms()
        assert [(p.start, p.stop) for p in form.pieces(2.0, 0.0)] == [(0.0, 1.0), (1.0, 2.0)]
        (piece,) = form.pieces(1.0, 1.0)
        assert piece(1.0) == 1.0  # the piece that starts at the point

    def test_long_table_gives_few_pieces_over_a_short_window(self):
        t = np.arange(10_001) * 0.01
        u = Table(t, np.sin(t))
        pieces = u.exact_terms().pieces(50.0, 50.05)
        assert len(pieces) == 5

    def test_no_exact_form(self):
        assert Function(np.sin).exact_terms() is None
        assert (Step() + Function(np.sin)).exact_terms() is None
        assert (2 * Function(np.sin)).exact_terms() is None

    def test_sine_terms(self):
        (piece,) = Sine(2.0, 3.0, 0.4, 1.0).exact_terms().pieces(0.0, 1.0)
        kinds = sorted((t.kind, t.freq) for t in piece.terms if t.freq)
        assert kinds == [("cos", 3.0), ("sin", 3.0)]

    @settings(max_examples=60, deadline=None)
    @given(
        time=st.floats(-5, 5),
        initial=st.floats(-10, 10),
        final=st.floats(-10, 10),
        slope=st.floats(-10, 10),
        start=st.floats(-5, 5),
        amplitude=st.floats(-10, 10),
        frequency=st.floats(-20, 20),
        phase=st.floats(-4, 4),
        period=st.floats(0.05, 3),
        width=st.floats(0.01, 0.99),
    )
    def test_round_trip_property(self, time, initial, final, slope, start, amplitude, frequency, phase,
                                 period, width):
        u = (
            Step(time, initial, final)
            + Ramp(slope, start)
            + Sine(amplitude, frequency, phase)
            + Pulse(amplitude, period, width, time)
        )
        t = np.concatenate([np.linspace(-6, 6, 301), u.breakpoints(-6, 6)])
        expected = u(t)
        # round-off scales with the largest term (the ramp reaches ~110)
        bound = 1e-13 * max(1.0, 10 * abs(slope))
        np.testing.assert_allclose(u.exact_terms()(t), expected, rtol=0, atol=bound)


# -- tables ------------------------------------------------------------------------------


class TestTable:
    def test_from_csv_with_header(self, tmp_path):
        path = tmp_path / "force.csv"
        path.write_text("time,force\n0,0\n1,2.5\n3,2.5\n")
        u = Table.from_csv(path)
        assert u.label == "force"
        np.testing.assert_array_equal(u.t, [0.0, 1.0, 3.0])
        np.testing.assert_array_equal(u.values, [0.0, 2.5, 2.5])
        assert u(0.5) == 1.25

    def test_from_csv_without_header_other_separators_and_comments(self, tmp_path):
        path = tmp_path / "u.txt"
        path.write_text("# measured input\n0 1\n\n0.5\t2\n1;4\n")
        u = Table.from_csv(path)
        np.testing.assert_array_equal(u.values, [1.0, 2.0, 4.0])
        assert u.label == "u"

    def test_from_csv_bad_line_names_file_and_line(self, tmp_path):
        path = tmp_path / "bad.csv"
        path.write_text("t,u\n0,1\n1,oops\n")
        with pytest.raises(InputError) as info:
            Table.from_csv(path)
        assert "line 3" in str(info.value) and str(path) in str(info.value)
        path.write_text("0,1,2\n")
        with pytest.raises(InputError, match="two columns"):
            Table.from_csv(path)
        path.write_text("t,u\n")
        with pytest.raises(InputError, match="no samples"):
            Table.from_csv(path)
        with pytest.raises(InputError, match="Cannot read"):
            Table.from_csv(tmp_path / "missing.csv")

    def test_from_csv_decreasing_times(self, tmp_path):
        path = tmp_path / "unsorted.csv"
        path.write_text("0,0\n2,1\n1,2\n")
        with pytest.raises(InputError) as info:
            Table.from_csv(path)
        assert info.value.source == str(path)
        assert "strictly increasing" in str(info.value)

    @pytest.mark.parametrize(
        "t, values, message",
        [
            ([0.0, 1.0, 1.0], [0, 1, 2], r"sample 2 \(t = 1.0\) does not come after sample 1"),
            ([0.0, 2.0, 1.0], [0, 1, 2], "strictly increasing"),
            ([0.0, 1.0], [0.0], "2 samples but `Table.values` has 1"),
            ([], [], "at least one sample"),
            ([0.0, np.nan], [0, 1], "must be finite"),
            ([0.0, 1.0], [0, np.inf], "must be finite"),
            ([[0.0, 1.0]], [[0, 1]], "must be 1-D"),
            (["a", "b"], [0, 1], "real numbers"),
        ],
    )
    def test_bad_tables(self, t, values, message):
        with pytest.raises(InputError, match=message):
            Table(t, values)

    def test_samples_are_copied_and_read_only(self):
        t = np.array([0.0, 1.0])
        u = Table(t, [0.0, 1.0])
        t[1] = 5.0
        assert u.t[1] == 1.0
        with pytest.raises(ValueError):
            u.values[0] = 3.0


# -- validation and coercion -------------------------------------------------------------


class TestValidation:
    @pytest.mark.parametrize(
        "make, message",
        [
            (lambda: Step(time="1"), r"`Step.time` must be a finite real number; got '1'"),
            (lambda: Ramp(slope=np.nan), "`Ramp.slope` must be a finite real number"),
            (lambda: Sine(frequency=True), "`Sine.frequency`"),
            (lambda: Pulse(period=0.0), "`Pulse.period` must be positive"),
            (lambda: Pulse(width=1.0), "strictly between 0 and 1"),
            (lambda: Function(3), "must be callable"),
            (lambda: Sum(Step()), "sequence of signals"),
            (lambda: Sum(["x"]), r"`Sum.terms\[0\]` must be a signal"),
            (lambda: Terms((Term(np.inf),)), r"`Terms.terms\[0\].coef`"),
            (lambda: Term(1.0, kind="tan"), "'cos' or 'sin'"),
        ],
    )
    def test_messages_name_the_field(self, make, message):
        with pytest.raises(InputError, match=message):
            make()

    def test_as_signal(self):
        assert as_signal(2) == Constant(2.0)
        assert isinstance(as_signal(np.sin), Function)
        with pytest.raises(InputError, match="`u` must be a signal"):
            as_signal("step")

    def test_as_signals(self):
        assert as_signals(None, ("a", "b")) == (Constant(0.0), Constant(0.0))
        assert as_signals(Step(), ("F",)) == (Step(),)
        assert as_signals({"b": 1.0}, ("a", "b")) == (Constant(0.0), Constant(1.0))
        assert as_signals([Step(), 2.0], ("a", "b")) == (Step(), Constant(2.0))
        with pytest.raises(InputError, match="has 1 signal but the system has 2 inputs"):
            as_signals([Step()], ("a", "b"))
        with pytest.raises(InputError, match=r"2 inputs \(a, b\)"):
            as_signals(Step(), ("a", "b"))
        with pytest.raises(InputError, match="'c', which is not an input"):
            as_signals({"c": Step()}, ("a", "b"))
        with pytest.raises(InputError, match="no inputs"):
            as_signals(Step(), ())

    def test_piece_and_form_helpers(self):
        piece = Piece(0.0, 1.0, (Term(1.0), Term(2.0, power=1)))
        assert piece(0.5) == 2.0
        form = ExactForm.of(Piece(-math.inf, math.inf, (Term(1.0),))).scaled(3.0)
        assert form(np.array([0.0, 10.0])).tolist() == [3.0, 3.0]


def test_input_jumps_are_the_left_limits_and_values_at_each_jump():
    from odelab.signals import Pulse, Ramp, Sine, Step, input_jumps

    step, ramp = Step(time=1.0, initial=2.0, final=-1.0), Ramp(slope=3.0, start=0.5)
    j = input_jumps([step, ramp], 0.0, 3.0)  # the ramp's kink at 0.5 too: both points on its curve
    assert j["t"] == [0.5, 1.0] and j["after"] == [[2.0, 0.0], [-1.0, 1.5]]
    assert j["before"][0] == [2.0, 0.0] and j["before"][1][0] == 2.0
    assert j["before"][1][1] == pytest.approx(1.5, abs=3 * 4 * np.finfo(float).eps)  # slope 3, one ulp earlier
    assert input_jumps([Sine()], 0.0, 3.0) is None  # no breakpoints
    assert input_jumps([step], 1.0, 3.0) is None  # a jump at t0 is the start, not inside the span
    assert input_jumps([step], 3.0, 0.0) == {"t": [1.0], "before": [[2.0]], "after": [[-1.0]]}  # in increasing t
    pulse = input_jumps([Pulse(amplitude=1.0, period=1.0, width=0.5)], 0.0, 2.1)
    assert pulse["t"] == [0.5, 1.0, 1.5, 2.0]
    assert [b + a for b, a in zip(pulse["before"], pulse["after"])] == [[1.0, 0.0], [0.0, 1.0]] * 2
