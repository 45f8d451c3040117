"""leolink.io.atomic.to_jsonable: numpy values as Python ones, NaN and +-inf as None, keys
as strings, objects JSON cannot hold kept as they are."""

import math

import numpy as np

from leolink.io.atomic import to_jsonable


def test_numpy_numbers_and_arrays_become_python_values_and_non_finite_none():
    tree = {
        "a": np.float32(0.1),
        "b": np.arange(3),
        "c": (1, 2.5, math.nan),
        "d": np.array([[1.0, np.inf], [-np.inf, 0.5]]),
        "e": np.bool_(True),
        "f": [np.int8(-3), np.uint64(2**64 - 1), np.float64(1e-310)],
    }
    out = to_jsonable(tree)
    assert out == {
        "a": 0.10000000149011612,  # the float32's own value, not its shortest decimal
        "b": [0, 1, 2],
        "c": [1, 2.5, None],
        "d": [[1.0, None], [None, 0.5]],
        "e": True,
        "f": [-3, 2**64 - 1, 1e-310],
    }
    types = tuple(type(v) for v in (out["b"][0], out["f"][0], out["a"], out["e"]))
    assert types == (int, int, float, bool)
    assert math.copysign(1.0, to_jsonable([-0.0])[0]) == -1.0


def test_other_trees_keep_their_objects_and_string_keys():
    class Tag:
        pass

    tag = Tag()
    out = to_jsonable({"t": [np.float64(math.nan), tag], "big": 2**70})
    assert out == {"t": [None, tag], "big": 2**70}  # (an integer beyond 64 bits as it is)
    assert out["t"][1] is tag
    assert to_jsonable({1: np.int64(4), None: [math.inf]}) == {"1": 4, "None": [None]}
