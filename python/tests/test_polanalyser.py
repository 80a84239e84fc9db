"""docs/python.md's example: psns and polanalyser demosaic the same emulated frame alike, and both
are scored against the emulator's truth. A wrong angle convention on either side (an offset or a
mirrored AoLP) shows up here as tens of degrees."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))


def test_psns_and_polanalyser_agree():
    import polanalyser  # noqa: F401  installed by .ci/run (tools/test): missing is a failure

    from compare_polanalyser import compare

    rows, between = compare(width=256, height=192, seed=2)
    (n1, med1, p99_1), (n2, med2, p99_2) = rows
    assert between < 0.05, between
    assert med1 < 3.0 and med2 < 3.0, rows
    assert abs(med1 - med2) < 0.1 * max(med1, med2), rows
