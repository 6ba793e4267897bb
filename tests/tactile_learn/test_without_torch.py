"""A deployment installs numpy and onnxruntime, not torch: the library's inference side and the
test suite's collection must both work with torch absent (torch tests skip with a reason)."""

from __future__ import annotations

import subprocess
import sys

from tests.paths import REPO_ROOT

ROOT = REPO_ROOT

# Makes `import torch` fail as it does where torch is not installed (ModuleNotFoundError), without
# touching sys.modules (scipy inspects sys.modules["torch"] when it is present).
BLOCK_TORCH = """
import sys

class _NoTorch:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "onnxscript"):
            raise ModuleNotFoundError(f"No module named {name!r} (blocked by the no-torch test)")
        return None

sys.meta_path.insert(0, _NoTorch())
"""


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", BLOCK_TORCH + code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


def test_the_blocker_really_blocks_torch() -> None:
    # guards the two tests below against passing because the block does nothing
    done = _run("import torch")
    assert done.returncode != 0 and "blocked by the no-torch test" in done.stderr


def test_the_suite_collects_without_torch() -> None:
    done = _run(
        "import pytest; sys.exit(pytest.main(['--collect-only', '-q', '-rs', '-p', 'no:cacheprovider', 'tests']))"
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "error" not in done.stdout.splitlines()[-1].lower(), done.stdout[-3000:]
    # what needs torch says so when it skips
    assert "torch (training extra) is not installed" in done.stdout


def test_classical_methods_and_shipped_models_run_without_torch() -> None:
    code = """
import numpy as np
from synth.dataset import simulate_shard
from synth.scene import load_scene
from tactile_learn.methods import resolve_method

for task_name, scene_name, methods in [
    ("strips", "strips16", ("intersection", "strips16")),
    ("fsr", "fsr6", ("triangulation", "fsr")),
]:
    scene = load_scene(scene_name)
    readings = simulate_shard(scene, 0, 0, 4)["readings"]
    for method in methods:
        out = resolve_method(task_name, method, scene).predict(readings)
        assert len(out) == 4 and np.isfinite(out).all(), (method, out)
mods = [m for m in sys.modules if m.split(".")[0] == "torch" and sys.modules[m] is not None]
assert not mods, mods
print("ok")
"""
    done = _run(code)
    assert done.returncode == 0 and done.stdout.strip().endswith("ok"), done.stdout[-2000:] + done.stderr[-3000:]
