import pytest

from helpers import CONFIGS
from raindrop_tools.config import ConfigError, RunConfig, config_from_dict, dump_config, load_config, parse_overrides
from raindrop_tools.schedule import lr_at


@pytest.mark.parametrize("name", ["paper", "compact", "smoke"])
def test_shipped_configs_load(name):
    cfg = load_config(CONFIGS / f"{name}.yaml")
    assert cfg.name == name
    assert cfg.data.crop >= cfg.loss.ssim_window
    # the dump round-trips
    import yaml

    assert config_from_dict(yaml.safe_load(dump_config(cfg))) == cfg


def test_paper_config_is_the_paper():
    cfg = load_config(CONFIGS / "paper.yaml")
    assert cfg == RunConfig(name="paper", data=cfg.data)  # the defaults are the paper's
    n = cfg.network
    assert (n.rdn.width, n.rdn.expanded, n.rdn.blocks) == (64, 256, 6)
    assert (n.rrn.width, n.rrn.expanded, n.rrn.blocks, n.rrn.global_residual) == (64, 256, 8, False)
    assert (n.rfn.width, n.rfn.blocks) == (64, 2)
    t = cfg.train
    assert (t.batch_size, t.lr, t.lr_end, t.decay_start, t.decay_end) == (32, 1e-3, 1e-4, 0.4, 0.8)
    assert cfg.data.crop == 100 and cfg.data.flip


def test_unknown_key_is_an_error():
    with pytest.raises(ConfigError, match="train.batchsize"):
        config_from_dict({"train": {"batchsize": 3}})


def test_types_are_checked_and_coerced():
    cfg = config_from_dict({"train": {"lr": "1e-3", "lr_end": 1e-4}})  # YAML reads 1e-3 as a string
    assert cfg.train.lr == 1e-3
    with pytest.raises(ConfigError, match="train.batch_size"):
        config_from_dict({"train": {"batch_size": "many"}})
    with pytest.raises(ConfigError, match="data.flip"):
        config_from_dict({"data": {"flip": "yes"}})


def test_partial_nested_mapping_keeps_defaults():
    cfg = config_from_dict({"network": {"rrn": {"width": 16}}})
    assert cfg.network.rrn.width == 16 and cfg.network.rrn.blocks == 8 and cfg.network.rdn.blocks == 6


def test_overrides_and_range_checks():
    cfg = config_from_dict({}, parse_overrides(["train.stage1_steps=7", "pipeline.dilation=5"]))
    assert cfg.train.stage1_steps == 7 and cfg.pipeline.dilation == 5
    with pytest.raises(ConfigError, match="decay_start"):
        config_from_dict({"train": {"decay_start": 0.9, "decay_end": 0.5}})
    with pytest.raises(ConfigError, match="global_residual"):
        config_from_dict({"network": {"rdn": {"global_residual": True}}})
    with pytest.raises(ConfigError):
        parse_overrides(["no-equals-sign"])
    # The networks only ever see even sizes in the pipelines, so they train on even crops.
    with pytest.raises(ConfigError, match="data.crop must be an even number"):
        config_from_dict({"data": {"crop": 63}})


def test_relative_data_path_resolves_against_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = load_config(CONFIGS / "smoke.yaml")
    assert cfg.data.train == str(tmp_path / "data" / "smoke")


def test_lr_schedule():
    args = dict(total=100, lr=1e-3, lr_end=1e-4, decay_start=0.4, decay_end=0.8)
    assert lr_at(0, **args) == 1e-3
    assert lr_at(40, **args) == 1e-3
    assert lr_at(60, **args) == pytest.approx(5.5e-4)
    assert lr_at(80, **args) == pytest.approx(1e-4)
    assert lr_at(99, **args) == pytest.approx(1e-4)
    values = [lr_at(s, **args) for s in range(100)]
    assert all(a >= b for a, b in zip(values, values[1:]))


@pytest.mark.parametrize("override,match", [
    ("train.betas=[2, 3]", "betas must be in"), ("train.betas=[0.9, .nan]", "betas must be in"),
    ("train.lr=.nan", "finite and > 0"), ("train.lr=.inf", "finite and > 0"), ("train.lr_end=0", "finite and > 0"),
    ("seed=-1", "seed must be in"), ("seed=9223372036854775808", "seed must be in"),
])
def test_optimizer_and_seed_values_are_range_checked(override, match):
    """These reached Adam or numpy and ended in a traceback (or, lr=inf, in NaN weights saved
    as the latest checkpoint)."""
    with pytest.raises(ConfigError, match=match):
        config_from_dict({}, parse_overrides([override]))


@pytest.mark.parametrize(
    "text, where",
    [
        ("a: [1, 2\nb: 3\n",
         "while parsing a flow sequence (line 1, column 4): expected ',' or ']', but got ':' (line 2, column 2)"),
        ("train:\n  lr: 1\n  lr: 2\n", "the key 'lr' is given twice (line 3, column 3)"),
        ('a: "x\n', "found unexpected end of stream (line 2, column 1)"),
        ("a: 1\n---\nb: 2\n", "expected a single document in the stream (line 1, column 1): but found another document"),
        ("a: &x 1\nb: &x 2\n", "found duplicate anchor 'x'; first occurrence (line 1, column 4): second occurrence"),
        ("lr: !!int x\n", "a value YAML cannot construct (ValueError"),
        ("? [1, 2]\n: 3\n", "a value YAML cannot construct (TypeError"),
        ("a: \x07\n", "special characters are not allowed (character 4)"),
    ],
)
def test_a_yaml_mistake_is_one_line_that_says_where(tmp_path, text, where):
    # PyYAML's own message quotes the text over several lines, with a caret under it; its
    # constructors raised ValueError or TypeError (a traceback) for a value its tag cannot take.
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as e:
        load_config(path)
    assert "\n" not in str(e.value) and where in str(e.value), str(e.value)


@pytest.mark.parametrize("item", ["train.lr=[1", "train.lr=!!int x"])
def test_an_override_that_is_not_yaml_is_one_line(item):
    with pytest.raises(ConfigError) as e:
        parse_overrides([item])
    assert "\n" not in str(e.value) and "the value is not YAML" in str(e.value), str(e.value)


def test_a_yaml_error_without_a_message_still_says_something():
    import yaml

    from raindrop_tools.config import yaml_error_text

    assert yaml_error_text(yaml.YAMLError()) == "YAMLError"
