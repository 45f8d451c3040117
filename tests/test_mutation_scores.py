"""tools/mutation_scores.py's named modes stay complete: ``--compiled`` lists every
``@compiled.jit`` loop and ``--jitable`` every ``@compiled.jitable`` function of the
package (a new one would otherwise be mutated by no run: mutmut skips decorated
functions), and the scratch copy loses exactly the decorator lines of the listed
functions."""

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("mutation_scores", ROOT / "tools/mutation_scores.py")
ms = importlib.util.module_from_spec(_spec)
sys.modules["mutation_scores"] = ms
_spec.loader.exec_module(ms)


def _decorated(decorators):
    """module -> the functions under one of ``decorators`` in src/leolink, read line by
    line."""
    found = {}
    for path in sorted((ROOT / "src" / "leolink").rglob("*.py")):
        lines = path.read_text().splitlines()
        for line, nxt in zip(lines, lines[1:], strict=False):
            m = re.match(r"def (\w+)\(", nxt)
            if line.strip() in decorators and m:
                module = path.relative_to(ROOT / "src" / "leolink").with_suffix("").as_posix()
                found.setdefault(module, set()).add(m.group(1))
    return found


def test_jitable_mode_lists_every_jitable_function_of_the_package():
    table, decorators = ms.NAMED["jitable"]
    listed = {module: set(functions) for module, (functions, _) in table.items()}
    assert listed == _decorated(decorators)


def test_compiled_mode_lists_every_compiled_loop_of_the_package():
    table, decorators = ms.NAMED["compiled"]
    listed = {module: set(functions) for module, (functions, _) in table.items()}
    assert listed == _decorated(decorators)


@pytest.mark.parametrize("mode", sorted(ms.NAMED))
def test_every_listed_test_file_exists(mode):
    for module, (_, tests) in ms.NAMED[mode][0].items():
        for t in tests:
            assert t.startswith("-") or (ROOT / t.split("::")[0]).exists(), (module, t)


def test_undecorating_drops_only_the_listed_functions_decorators(tmp_path):
    src = tmp_path / "m.py"
    text = (
        "@compiled.jitable\ndef a(x):\n    return x\n\n"
        "@leolink.compiled.jitable\ndef b(x):\n    return x\n\n"
        "@compiled.jitable\ndef c(x):\n    return x\n\n"
        "@compiled.jit\ndef d(x):\n    return x\n"
    )
    src.write_text(text)
    ms._undecorate(src, ms.NAMED["jitable"][1], ("a", "b"))
    assert src.read_text() == text.replace("@compiled.jitable\ndef a", "def a").replace(
        "@leolink.compiled.jitable\n", ""
    )
    with pytest.raises(SystemExit, match="expected 1 functions"):  # d is not jitable
        ms._undecorate(src, ms.NAMED["jitable"][1], ("d",))


def test_functions_select_the_mutants_of_those_functions_and_methods_alone():
    import fnmatch

    pats = ms._patterns("sim/handover/trigger_run", "numpy", ("_live_sats", "_on_cells"))
    module = "leolink.sim.handover.trigger_run."
    names = {
        module + "xǁTriggerRunǁ_live_sats__mutmut_3": True,
        module + "x__on_cells__mutmut_1": True,
        module + "xǁTriggerRunǁ_axis__mutmut_1": False,
        module + "xǁTriggerRunǁ_not_live_sats__mutmut_1": False,
        "leolink.sim.handover.local_axis.xǁLocalAxisǁ_live_sats__mutmut_1": False,
    }
    for name, chosen in names.items():
        assert any(fnmatch.fnmatch(name, p) for p in pats) == chosen, name
    # the compiled mode's loops, and the functions added to them
    pats = ms._patterns("engine/__init__", "compiled", ("_serve_compiled",))
    assert fnmatch.fnmatch("leolink.engine.x__serve_rows__mutmut_8", pats[0])
    assert any(fnmatch.fnmatch("leolink.engine.xǁLinkEngineǁ_serve_compiled__mutmut_5", p)
               for p in pats)  # fmt: skip
