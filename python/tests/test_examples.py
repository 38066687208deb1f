"""The Python examples of examples/ run, small (`--quick`), on the cpu backend: each asserts
what it shows (the plate's force rises as it presses, the drag's terminal speed is reached, the
impact spends its energy, a wet agglomerate survives a slow drop and breaks in a fast one) and
exits 0."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.parametrize(
    "script, says",
    [
        ("python_plate_press.py", "into the bed's top"),
        ("python_drag_coupling.py", "terminal"),
        ("python_from_arrays.py", "['glass', 'steel']"),
        ("python_agglomerate.py", "1 piece before, 1 after"),
    ],
)
def test_an_example_runs_and_shows_what_it_claims(script, says, tmp_path):
    run = subprocess.run(
        [sys.executable, str(EXAMPLES / script), "--quick", "--backend", "cpu"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert says in run.stdout, run.stdout
