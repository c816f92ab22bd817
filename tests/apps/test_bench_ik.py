"""apps/bench/ik.py's closed-form tables: the Puma's and the UR's batch rows and found-bullet
come from one _closed_form_batch_rows / _closed_form_found, each row carrying its own
measurement (numbers chosen here, so every figure in the text can be traced to its input)."""

from __future__ import annotations

from deltagen.apps.bench import ik as bench_ik
from deltagen.apps.bench.timing import Stat


def _analytic(scale: float) -> dict:
    """A closed-form measurement with distinct numbers: kernel 1000 scale ns, api 1500
    scale, numpy 9000 scale, one-pose api 4000 scale."""
    return {
        "k": 8,
        "n": 2000,
        "ref_n": 500,
        "found": 0.99875,
        "valid_per_pose": 3.5,
        "max_residual": 2.5e-12,
        "batch": {
            "kernel": Stat([1000.0 * scale]),
            "api": Stat([1500.0 * scale]),
            "numpy": Stat([9000.0 * scale]),
        },
        "single": {"api": Stat([4000.0 * scale])},
    }


def test_the_ur_rows_carry_their_own_numbers_and_target():
    lines = "\n".join(bench_ik.render_ur(_analytic(2.0), markdown=True))
    ur = bench_ik.UR_ROBOT
    assert f"{ur}: all 8 closed-form branches, C kernel `_core.ik_all(T)`, batch of 2,000" in lines
    assert "| 2 [2, 2] |" in lines  # the kernel: 2000 ns = 2 us
    assert "| 3 [3, 3] | <= 2 " in lines  # the API, against its 2 us target: missed
    assert f"{ur}: all 8 branches, numpy solver (reference backend), batch of 500" in lines
    assert "| 18 [18, 18] |" in lines
    assert "UR closed form: the original q is among the valid branches for 99.875 %" in lines
    assert "(3.50 valid branches per pose on average)" in lines and "2.5e-12" in lines


def test_both_tables_share_the_batch_rows():
    a = _analytic(1.0)
    puma = bench_ik._closed_form_batch_rows(a, "", "analytic_batch_ns")
    ur = bench_ik._closed_form_batch_rows(a, "UR5: ", "ur5_batch_ns")
    assert [r[1:] for r in puma] == [r[1:] for r in ur]  # same numbers, same verdicts
    assert all(u[0] == "UR5: " + p[0] for p, u in zip(puma, ur))
    assert puma[1][2].startswith("<= 2 ") and puma[0][2] == puma[2][2] == "-"
