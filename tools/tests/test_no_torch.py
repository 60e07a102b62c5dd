"""The light environment: the reference pipeline, metrics and evaluation import without torch."""

import subprocess
import sys

from helpers import FIXTURE_MODELS, TOOLS

BLOCK_TORCH = (
    "import sys\n"
    "class _Block:\n"
    "    def find_spec(self, name, path=None, target=None):\n"
    "        if name == 'torch' or name.startswith('torch.') or name in ('pytorch_msssim', 'onnx', 'onnxscript'):\n"
    "            raise ModuleNotFoundError('blocked: ' + name)\n"
    "sys.meta_path.insert(0, _Block())\n"
)


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BLOCK_TORCH + code], capture_output=True, text=True, cwd=TOOLS)


def test_light_modules_import_without_torch():
    r = _run(
        "import raindrop_tools, raindrop_tools.reference, raindrop_tools.metrics, raindrop_tools.evaluate, "
        "raindrop_tools.data, raindrop_tools.edge, raindrop_tools.imageio, raindrop_tools.config, "
        "raindrop_tools.morphology, raindrop_tools.contract, raindrop_tools.realpairs, "
        "raindrop_tools.realism\n"
        "assert 'torch' not in sys.modules\n"
        "from raindrop_tools.reference import RaindropRemover\n"
        f"r = RaindropRemover({str(FIXTURE_MODELS)!r}, threads=1)\n"
        "import numpy as np\n"
        "print(r.remove(np.zeros((9, 11, 3), np.uint8)).output.shape)\n"
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "(9, 11, 3)"


def test_the_block_works():
    # guards the test above: if blocking failed to block, it would prove nothing
    r = _run("import raindrop_tools.networks")
    assert r.returncode != 0 and "blocked: torch" in r.stderr
