"""Hostile input: the file loaders either load or raise the documented one-line error with a
location — never a traceback from inside numpy or jax (hypothesis)."""

import re
import string

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from diffguide.io import read_rails_csv
from diffguide.io.config import load_config

LOCATED = re.compile(r"^\S+\.(csv|toml)(:\d+)?: ")

csv_cell = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**6), 10**6).map(str),
    st.text(alphabet=string.printable, max_size=8),
    st.sampled_from(["1", "2", "", " ", "nan", "inf", "-0", "1e400", '"', ",,"]),
)
csv_row = st.lists(csv_cell, min_size=0, max_size=6).map(",".join)
csv_text = st.lists(csv_row, min_size=0, max_size=8).map(
    lambda rows: "\n".join(["rail,s_mm,vertical_um,horizontal_um", *rows])
)


def _loads_or_located_error(load, path):
    try:
        load(path)
    except ValueError as exc:
        message = str(exc)
        assert LOCATED.match(message), message
        assert "\n" not in message
    except OSError as exc:
        assert str(path) in str(exc)


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=st.one_of(csv_text, st.text(max_size=200)))
def test_rails_csv_loader_on_arbitrary_text(tmp_path, text):
    path = tmp_path / "rails.csv"
    path.write_text(text, encoding="utf-8")
    _loads_or_located_error(read_rails_csv, path)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    s=st.lists(st.floats(-1e5, 1e5), min_size=4, max_size=12),
    v=st.floats(-1e4, 1e4),
    rail=st.sampled_from([1, 2]),
)
def test_rails_csv_loader_on_numeric_but_odd_samples(tmp_path, s, v, rail):
    # valid numbers, odd geometry: duplicates, huge ranges, samples 1e-9 mm apart
    path = tmp_path / "rails.csv"
    path.write_text(
        "rail,s_mm,vertical_um,horizontal_um\n" + "".join(f"{rail},{x!r},{v!r},0\n" for x in s),
        encoding="utf-8",
    )
    _loads_or_located_error(read_rails_csv, path)


@settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=200))
def test_rails_csv_loader_on_arbitrary_bytes(tmp_path, data):
    path = tmp_path / "rails.csv"
    path.write_bytes(data)
    _loads_or_located_error(read_rails_csv, path)


toml_value = st.one_of(
    st.integers(-(10**9), 10**9).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(lambda v: repr(v).replace("inf", "inf")),
    st.text(alphabet=string.ascii_letters, max_size=6).map(lambda s: f'"{s}"'),
    st.lists(st.integers(-1000, 1000), max_size=3).map(
        lambda v: "[" + ", ".join(map(str, v)) + "]"
    ),
    st.sampled_from(["true", "[]", "{}", '"O"', '"hertz"', "1e999", "nan", "-nan"]),
)
sections = st.sampled_from(
    ["table", "guideway", "carriage", "screw", "machine", "points", "ribs", "x"]
)
keys = st.sampled_from(
    [
        "length_mm",
        "thickness_mm",
        "mesh_nx",
        "rail_y_mm",
        "carriage_x_mm",
        "law",
        "arrangement",
        "preload_fraction",
        "P1",
        "nut_xy_mm",
        "stroke_mm",
        "axis",
        "bogus",
    ]
)
toml_text = st.lists(
    st.tuples(sections, st.lists(st.tuples(keys, toml_value), max_size=4)), max_size=4
).map(
    lambda secs: "\n".join(
        f"[{s}]\n" + "\n".join(f"{k} = {v}" for k, v in body) for s, body in secs
    )
)


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=st.one_of(toml_text, st.text(max_size=200)))
def test_config_loader_on_arbitrary_text(tmp_path, text):
    path = tmp_path / "machine.toml"
    path.write_text(text, encoding="utf-8")
    _loads_or_located_error(load_config, path)
