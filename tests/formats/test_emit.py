"""The importers' TOML writer: what it writes reads back as the same values, bit for bit, with its comments."""

import math
import tomllib

import pytest

from odelab.formats.emit import Section, toml_value, write_toml


def test_values_read_back_exactly():
    values = {"third": 1 / 3, "tiny": 5e-324, "big": 1.7976931348623157e308, "int": 12, "neg": -0.0,
              "vector": [1e-4, 1e-4, 1e-5], "matrix": [[0.0, 1.0], [-2.5, -0.1]], "flag": True,
              "text": 'a "quote" \\ and\ttab', "table": {"h": "0", "v": "-0.9*v"}, "inf": math.inf}
    sec = Section("parameters")
    for key, value in values.items():
        sec.add(key, value, comment=f"from line {len(sec.entries) + 1}")
    back = tomllib.loads(write_toml([sec], header="imported from rigid.m"))["parameters"]
    assert back == values
    assert math.copysign(1, back["neg"]) == -1.0


def test_names_that_need_quotes_and_gaps():
    init = Section('initial', comment="from the call on line 3")
    init.add("y", "sqrt(3/2)")
    init.add("der(y)", 0)
    time = Section("time")
    time.add("stop", gap="the function file has no solver call: give --call or write the end time")
    text = write_toml([init, time])
    assert '"der(y)" = 0' in text and "# GAP: the function file has no solver call" in text
    assert "# stop = ..." in text
    assert tomllib.loads(text) == {"initial": {"y": "sqrt(3/2)", "der(y)": 0}, "time": {}}


def test_a_nan_and_an_array_of_tables():
    cases = [Section("case", array=True), Section("case", array=True)]
    cases[0].add("name", "ode23")
    cases[1].add("name", "ode45")
    assert tomllib.loads(write_toml(cases)) == {"case": [{"name": "ode23"}, {"name": "ode45"}]}
    assert toml_value(math.nan) == "nan"
    with pytest.raises(TypeError):
        toml_value(object())
