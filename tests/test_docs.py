"""The documentation builds with warnings as errors (notebooks executed on short horizons)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parent.parent


def test_docs_build_with_warnings_as_errors(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         str(ROOT / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True,
    )
    warnings = [line for line in result.stderr.splitlines()
                if "WARNING" in line and "IPKernelApp" not in line or "ERROR" in line]
    assert result.returncode == 0, "\n".join(warnings) or result.stderr[-3000:]
    for page in ("index", "getting-started", "api", "theory/frit", "theory/errata",
                 "notebooks/03_online_frit_tuning"):
        assert (tmp_path / "html" / f"{page}.html").exists(), page
    api = (tmp_path / "html" / "api.html").read_text()
    assert "frit_tuner" in api and "adaptive_smc" in api and "draw_block_diagram" in api
