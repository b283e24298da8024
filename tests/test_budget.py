"""The memory budget parser (qfg.budget): every spelling of a size, a percentage and unlimited,
every bad value refused naming its argument, and unlimited budgets that never overflow where
they are compared or printed (``memory=``, ``--memory``, ``$QFG_MEMORY_BUDGET``)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from qfg import budget
from qfg.budget import UNLIMITED, format_bytes, memory_budget, parse_bytes
from qfg.inference import FactorModel, JunctionTree, MemoryBudgetError, solve_task

NAMES = st.sampled_from(["memory=", "--memory", "$QFG_MEMORY_BUDGET"])
UNITS = {"": 1, "K": 2 ** 10, "M": 2 ** 20, "G": 2 ** 30, "T": 2 ** 40}


def _spell(unit: str, suffix: str, case: str) -> str:
    word = unit + ("" if not unit and suffix == "iB" else suffix)
    return word.lower() if case == "lower" else word.upper() if case == "upper" else word


sizes = st.tuples(
    st.one_of(st.integers(1, 10 ** 6), st.floats(1e-3, 1e6, allow_nan=False)),
    st.sampled_from(sorted(UNITS)), st.sampled_from(["", "B", "iB"]),
    st.sampled_from(["lower", "upper", "as is"]), st.sampled_from(["", " "]))


@given(sizes, NAMES)
def test_every_spelling_of_a_size_is_its_bytes(size, name):
    number, unit, suffix, case, space = size
    text = f"{number}{space}{_spell(unit, suffix, case)}"
    want = int(float(number) * UNITS[unit])
    if want < 1:                       # a fraction of a byte: refused, naming the argument
        with pytest.raises(ValueError, match=f"^{_re(name)}: expected a positive"):
            parse_bytes(text, name=name)
        return
    got = parse_bytes(text, name=name)
    assert type(got) is int and got == min(want, UNLIMITED)


@given(st.one_of(st.text(max_size=12), st.integers(-10 ** 30, 10 ** 30),
                 st.floats(allow_nan=True, allow_infinity=True), st.booleans(), st.none()),
       NAMES)
def test_any_value_is_a_budget_or_a_value_error_naming_the_argument(value, name):
    try:
        got = parse_bytes(value, name=name)
    except ValueError as exc:
        msg = str(exc)
        assert msg.startswith(f"{name}: ") and "\n" not in msg
        return
    assert type(got) is int and 1 <= got <= UNLIMITED
    assert got // 8 >= 0 and np.int64(got) == got        # divides, fits numpy: no overflow
    assert isinstance(format_bytes(got), str)


@given(st.floats(0.01, 100.0), NAMES)
def test_a_percentage_is_a_share_of_the_machine(pct, name):
    got = parse_bytes(f"{pct}%", name=name)
    assert got == int(pct / 100 * budget.physical_memory())


@pytest.mark.parametrize("text", ["inf", "INF", "Infinity", "unlimited", "1e400", "1e400G",
                                  float("inf"), 1e300, 10 ** 400, "1e19"])
def test_unlimited_and_beyond_is_the_largest_budget(text):
    assert parse_bytes(text) == UNLIMITED == 2 ** 63 - 1
    assert format_bytes(parse_bytes(text)) == "unlimited"


@pytest.mark.parametrize("text, match", [
    ("0", "positive"), (0, "positive"), ("-1", "positive"), (-2 ** 40, "positive"),
    ("-inf", "positive"), ("nan", "NaN"), (float("nan"), "NaN"), ("garbage", "expected"),
    ("", "expected"), ("G", "expected"), ("2X", "expected"), (True, "expected"),
    ("0%", "percentage"), ("150%", "percentage"), ("nan%", "NaN"), ("0.1", "positive"),
])
def test_bad_budgets_name_the_argument(text, match):
    for name in ("memory=", "--memory", "$QFG_MEMORY_BUDGET"):
        with pytest.raises(ValueError, match=match) as info:
            parse_bytes(text, name=name)
        assert str(info.value).startswith(f"{name}: ")


def test_the_old_names_still_parse():
    from qfg.inference import memory

    assert memory.parse_bytes("1.5G") == int(1.5 * 2 ** 30)
    assert memory.memory_budget(1000) == 1000 and memory.DEFAULT_FRACTION == 0.5
    assert memory.parse_bytes("2GiB") == memory.parse_bytes("2G") == memory.parse_bytes("2GB")


def test_the_environment_is_named(monkeypatch):
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "garbage")
    with pytest.raises(ValueError, match=r"^\$QFG_MEMORY_BUDGET: "):
        memory_budget()
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "inf")
    assert memory_budget() == UNLIMITED
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "2K")
    assert memory_budget() == 2048 and memory_budget("1M") == 2 ** 20   # the call wins
    with pytest.raises(ValueError, match=r"^memory=: "):
        memory_budget("-3")


def _model():
    T = np.array([[0.9, 0.1], [0.2, 0.8]])
    return FactorModel([2, 2, 2], [(0, 1), (1, 2)], [T, T])


@pytest.mark.parametrize("memory", [float("inf"), "inf", "1e400", 10 ** 400])
def test_solve_task_with_an_unlimited_budget(memory):
    """OverflowError (int(inf)) before; then an unlimited budget was planned as max_table=1."""
    r = solve_task(_model(), "MAR", memory=memory)
    assert r.log10_z == pytest.approx(math.log10(2.0))
    assert JunctionTree(_model(), memory=memory).budget == UNLIMITED


def test_unlimited_from_the_environment(monkeypatch):
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "inf")
    assert solve_task(_model(), "PR").log10_z == pytest.approx(math.log10(2.0))


def test_a_refusal_prints_its_budget():
    with pytest.raises(MemoryBudgetError, match="memory budget 100 B") as info:
        solve_task(_model(), "MAR", memory=100)
    assert isinstance(info.value, budget.MemoryBudgetError) and info.value.budget == 100
    with pytest.raises(budget.MemoryBudgetError, match="> the memory budget unlimited"):
        budget.check_memory(1e300, UNLIMITED, "a test")
    budget.check_memory(1e18, UNLIMITED, "a test")


@pytest.mark.parametrize("value", ["inf", "1e400", "50%", "2GiB"])
def test_cli_memory_accepts_unlimited_and_percentages(tmp_path, capsys, value):
    from qfg.harness.cli import main
    from qfg.inference import write_uai

    write_uai(_model(), tmp_path / "m.uai", sidecar=False)
    rc = main(["uai", str(tmp_path / "m.uai"), "--task", "PR", "--memory", value,
               "--output", str(tmp_path / "m.PR")])
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "m.PR").read_text().startswith("PR\n")


@pytest.mark.parametrize("value", ["0", "-1G", "nan", "lots"])
def test_cli_memory_refuses_naming_the_option(tmp_path, capsys, value):
    from qfg.harness.cli import main
    from qfg.inference import write_uai

    write_uai(_model(), tmp_path / "m.uai", sidecar=False)
    rc = main(["uai", str(tmp_path / "m.uai"), "--task", "PR", f"--memory={value}",
               "--output", str(tmp_path / "m.PR")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "--memory: " in err
    assert not (tmp_path / "m.PR").exists()


def test_cli_environment_inf(tmp_path, capsys, monkeypatch):
    from qfg.harness.cli import main
    from qfg.inference import write_uai

    write_uai(_model(), tmp_path / "m.uai", sidecar=False)
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "inf")
    assert main(["uai", str(tmp_path / "m.uai"), "--task", "PR",
                 "--output", str(tmp_path / "m.PR")]) == 0
    monkeypatch.setenv("QFG_MEMORY_BUDGET", "-5")
    assert main(["uai", str(tmp_path / "m.uai"), "--task", "PR",
                 "--output", str(tmp_path / "m.PR")]) == 2
    assert "$QFG_MEMORY_BUDGET: " in capsys.readouterr().err


def _re(name: str) -> str:
    import re

    return re.escape(name)
