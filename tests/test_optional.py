"""Optional packages: a missing one is one line naming the extra that installs it (real imports
blocked in a fresh interpreter, not mocks of ipfit)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import ipfit
from ipfit._utils.optional import EXTRAS, MissingDependencyError, install_line, missing, require

SRC = str(Path(ipfit.__file__).resolve().parents[1])

# Run ipfit in a fresh interpreter in which the named top-level packages cannot be imported,
# as on an install without their extra.
_BLOCKED = textwrap.dedent("""
    import sys
    blocked = set(sys.argv[1].split(","))

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in blocked:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, Blocker())
    del sys.argv[1]
    """)


def _run_without(packages: str, code: str, tmp_path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _BLOCKED + textwrap.dedent(code), packages], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": SRC})


def test_every_extra_of_the_map_is_an_extra_of_the_package():
    import tomllib

    pyproject = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    extras = pyproject["project"]["optional-dependencies"]
    for module, extra in EXTRAS.items():
        assert extra in extras, (module, extra)
    assert install_line("distributed.client") == "pip install 'ipfit[dask]'"
    assert install_line("plotly.graph_objects") == "pip install 'ipfit[viewer]'"


def test_require_names_the_extra_and_is_an_import_error():
    with pytest.raises(MissingDependencyError, match=r"fit_many needs the optional package 'nosuchpkg'") as info:
        require("nosuchpkg.sub", "fit_many")
    assert isinstance(info.value, ImportError) and len(str(info.value).splitlines()) == 1
    assert missing(ModuleNotFoundError("No module named 'numpy_x'", name="numpy_x"), "x") is None


def test_fit_chunked_without_dask_says_which_extra(tmp_path):
    result = _run_without("dask,distributed", """
        import numpy as np, ipfit
        from ipfit.exceptions import IpfitError
        t = np.linspace(0, 6.28, 50)
        pts = np.column_stack([np.cos(t), np.sin(t)])
        try:
            ipfit.fit_chunked(pts, pts, 2)
        except IpfitError as exc:
            print(type(exc).__name__, exc)
        """, tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("Install it with: pip install 'ipfit[dask]'")
    assert "MissingDependencyError" in result.stdout


@pytest.mark.parametrize("argv,extra", [
    (["batch", "generated:2", "-o", "out", "--degree", "2", "--method", "3l", "-q"], "dask"),
    (["view", "res.json", "-o", "v.html"], "viewer"),
])
def test_a_command_without_its_extra_is_one_line(tmp_path, argv, extra):
    from ipfit.cli import main

    assert main(["fit", "boot", "-o", str(tmp_path / "res"), "--degree", "2", "--method", "3l", "-q",
                 "--no-picture", "--no-zero-set"]) == 0
    blocked = {"dask": "dask,distributed", "viewer": "plotly"}[extra]
    result = _run_without(blocked, f"""
        import sys
        from ipfit.cli import main
        sys.exit(main({argv!r}))
        """, tmp_path)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith(f"ipfit {argv[0]}: error:") and f"pip install 'ipfit[{extra}]'" in lines[0]
    assert "Traceback" not in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res.json"]  # nothing written


def test_reading_a_scanner_format_without_its_extra(tmp_path):
    np.savetxt(tmp_path / "x.txt", np.zeros((1, 3)))
    (tmp_path / "a.las").write_bytes(b"LASF" + bytes(400))
    result = _run_without("laspy,lazrs", """
        import sys
        from ipfit.cli import main
        sys.exit(main(["fit", "a.las", "-o", "r", "-q"]))
        """, tmp_path)
    assert result.returncode == 2, result.stderr
    assert "pip install 'ipfit[scanners]'" in result.stderr and len(result.stderr.strip().splitlines()) == 1
