"""summary.json's text (leolink.io.summary.json_text) against the standard library's encoder.

The reference is ``json.dumps(to_jsonable(obj), indent=2, allow_nan=False)``, the text
summary.json had before the faster encoder: real runs' summaries (a pass with per-UT
records, a Walker run on a rotating Earth) must give the same characters, and so must
generated trees whatever the depth at which the text is cut into pieces.
"""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.app.run import run
from leolink.config import load_config
from leolink.io.atomic import to_jsonable
from leolink.io.summary.json_text import json_pieces


def _reference(obj):
    return json.dumps(to_jsonable(obj), indent=2, allow_nan=False)


@pytest.mark.parametrize(
    ("config", "overrides"),
    [
        ("configs/paper.toml", ["run.start_s=-150", "run.duration_s=420"]),
        ("configs/examples/walker.toml", ["run.duration_s=20"]),
    ],
)
def test_a_real_summary_is_the_standard_librarys_text(config, overrides):
    summary = run(load_config(config, ["output.plots.enabled=false", *overrides])).summary
    text = "".join(json_pieces(summary))
    assert text == _reference(summary)
    assert len(text) > 10_000  # per-UT records, dwell lists: not a trivial tree
    assert "null" in text  # some statistic of the run is NaN (e.g. a UT never in outage)


_leaves = st.one_of(
    st.floats(),  # NaN and infinities included: null
    st.floats(width=32).map(np.float32),
    st.integers(),
    st.integers(-(2**62), 2**62).map(np.int64),
    st.booleans(),
    st.booleans().map(np.bool_),
    st.none(),
    st.text(max_size=6),  # non-ASCII too: escaped as the standard library does
)
_keys = st.one_of(st.text(max_size=3), st.integers(-3, 3), st.booleans(), st.floats(-2, 2))


def _grow(children):
    return st.one_of(
        st.lists(children, max_size=4),
        st.lists(children, max_size=4).map(tuple),
        st.lists(st.floats(), max_size=4).map(lambda xs: np.asarray(xs, float)),
        st.dictionaries(_keys, children, max_size=4),
    )


@settings(max_examples=400, deadline=None)
@given(st.recursive(_leaves, _grow, max_leaves=25), st.integers(0, 4))
def test_generated_trees_give_the_same_text_at_every_depth(tree, depth):
    """Keys that print alike (``1``, ``"1"``, ``True``) become one key, as to_jsonable
    makes them; pieces at any depth join to the whole text."""
    assert "".join(json_pieces(tree, depth)) == _reference(tree)


def test_keys_that_print_alike_are_one_key_and_the_last_value_wins():
    tree = {"a": {1: "int", "1": "str"}, 2.5: [], True: {}}
    text = "".join(json_pieces(tree))
    assert text == '{\n  "a": {\n    "1": "str"\n  },\n  "2.5": [],\n  "True": {}\n}'
    assert text == _reference(tree)


def test_what_json_cannot_encode_is_refused_as_json_refuses_it():
    with pytest.raises(TypeError) as ours:
        "".join(json_pieces({"x": [1, object()]}))
    with pytest.raises(TypeError) as theirs:
        _reference({"x": [1, object()]})
    assert str(ours.value) == str(theirs.value)
