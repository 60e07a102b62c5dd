"""Weights back from the exported graphs (onnx_weights.py), on the committed models."""
import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from helpers import CONFIGS, REPO  # noqa: E402
from raindrop_tools import networks  # noqa: E402
from raindrop_tools import onnx_weights as OW  # noqa: E402
from raindrop_tools.config import load_config  # noqa: E402


@pytest.mark.parametrize("config,folder", [("compact.yaml", "compact"), ("paper-cpu.yaml", "paper")])
def test_committed_models_come_back_exactly(config, folder):
    if not (REPO / "models" / folder / "rdn.onnx").is_file():
        pytest.skip(f"models/{folder} is not in this checkout")
    nets = networks.build_networks(load_config(CONFIGS / config).network)
    diffs = OW.load_model_folder(nets, REPO / "models" / folder)
    assert set(diffs) == {"rdn", "rrn", "rfn"} and max(diffs.values()) < 1e-4


def test_a_structure_that_does_not_fit_is_refused():
    nets = networks.build_networks(load_config(CONFIGS / "compact.yaml", [("network.rdn.blocks", 3)]).network)
    with pytest.raises(OW.OnnxWeightsError, match="convolutions in the graph"):
        OW.load_network(nets["rdn"], "rdn", REPO / "models" / "compact" / "rdn.onnx")


def test_a_difference_the_structure_hides_is_caught_by_onnxruntime():
    # paper.yaml has no global residual; models/paper was trained with one (paper-cpu.yaml)
    nets = networks.build_networks(load_config(CONFIGS / "paper.yaml").network)
    with pytest.raises(OW.OnnxWeightsError, match="differ from the graph"):
        OW.load_model_folder(nets, REPO / "models" / "paper")


def test_split_transposed_convolutions_come_back_as_they_were(tmp_path):
    """A folder whose conv4 was split into phase convolutions (phase_conv.py) loads the same
    weights as before the split: the transposed kernel is rebuilt exactly."""
    import shutil

    from raindrop_tools.phase_conv import rewrite_folder

    from helpers import FIXTURE_MODELS  # exported before the split: ConvTranspose

    shutil.copytree(FIXTURE_MODELS, tmp_path / "split")
    assert rewrite_folder(tmp_path / "split")["rdn"] == 1
    cfg = load_config(CONFIGS / "smoke.yaml").network
    before, after = networks.build_networks(cfg), networks.build_networks(cfg)
    OW.load_model_folder(before, FIXTURE_MODELS)
    diffs = OW.load_model_folder(after, tmp_path / "split")
    assert max(diffs.values()) < 1e-4
    for name in ("rdn", "rrn", "rfn"):
        for (k, a), (_, b) in zip(before[name].state_dict().items(), after[name].state_dict().items()):
            assert torch.equal(a, b), f"{name}.{k}"


def test_final_convolutions_on_the_phases_come_back_as_they_were(tmp_path):
    """A folder whose conv5 was folded onto conv4's phases (phase_final_conv.py, after the
    split and without inner padding) loads the same weights as before: conv5's kernel and bias
    are read back exactly from the phase-domain kernel."""
    import shutil

    from raindrop_tools import inner_padding, phase_conv, phase_final_conv

    from helpers import FIXTURE_MODELS

    folder = tmp_path / "folded"
    shutil.copytree(FIXTURE_MODELS, folder)
    phase_conv.rewrite_folder(folder)
    inner_padding.rewrite_folder(folder)
    assert phase_final_conv.rewrite_folder(folder) == {"rdn": 1, "rrn": 1, "rfn": 0}
    cfg = load_config(CONFIGS / "smoke.yaml").network
    before, after = networks.build_networks(cfg), networks.build_networks(cfg)
    OW.load_model_folder(before, FIXTURE_MODELS)
    diffs = OW.load_model_folder(after, folder)
    assert max(diffs.values()) < 1e-4
    for name in ("rdn", "rrn", "rfn"):
        for (k, a), (_, b) in zip(before[name].state_dict().items(), after[name].state_dict().items()):
            assert torch.equal(a, b), f"{name}.{k}"
