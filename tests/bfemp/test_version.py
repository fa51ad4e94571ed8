"""``bfemp --version`` names the version, the BLAS CHOLMOD runs on and the solvers installed."""

import pytest

import bfemp
from bfemp.cli import main
from solvers.blas import cholmod_blas


def test_version_reports_the_linear_algebra(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"bfemp {bfemp.__version__}"
    assert out[1].startswith(f"CHOLMOD BLAS: {cholmod_blas().name}")
    assert out[2].startswith("linear solvers: ") and "scipy" in out[2]
