"""Sharded manifests (raindrop-render --shard K/N): the parts read as their merge."""

import json
import shutil

import pytest

from raindrop_tools import dataset_stats
from raindrop_tools.data import DatasetError, read_manifest
from raindrop_tools.manifest import manifest_lines


def _split_into_parts(root, n):
    """The folder's manifest.jsonl as the parts n shards would have written (round-robin here:
    which shard took a sample does not matter to a reader)."""
    lines = (root / "manifest.jsonl").read_text().splitlines()
    (root / "manifest.jsonl").unlink()
    for k in range(n):
        (root / f"manifest.part-{k}-of-{n}.jsonl").write_text("".join(x + "\n" for x in lines[k::n]))
    return lines


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the tiny set's records have no drops
def test_parts_read_as_the_merged_manifest(tiny_dataset, tmp_path):
    whole = read_manifest(tiny_dataset)
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    lines = _split_into_parts(root, 3)
    assert [text for _, _, text in manifest_lines(root)] == sorted(lines, key=lambda x: json.loads(x)["id"])
    sharded = read_manifest(root)
    assert [s.id for s in sharded] == sorted(s.id for s in whole)
    assert {s.file for s in sharded} == {f"manifest.part-{k}-of-3.jsonl" for k in range(3)}
    assert dataset_stats.summarize(root)["samples"] == dataset_stats.summarize(tiny_dataset)["samples"]


def test_a_manifest_and_parts_overlapping_count_once(tiny_dataset, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    lines = (root / "manifest.jsonl").read_text().splitlines()
    (root / "manifest.part-0-of-2.jsonl").write_text(lines[0] + "\n" + lines[2] + "\n")
    assert len(read_manifest(root)) == len(lines)


def test_a_different_record_under_one_id_is_refused(tiny_dataset, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    first = json.loads((root / "manifest.jsonl").read_text().splitlines()[0])
    first["variant"] = 99
    (root / "manifest.part-1-of-2.jsonl").write_text(json.dumps(first) + "\n")
    with pytest.raises(DatasetError, match=f"manifest.part-1-of-2.jsonl:1: duplicate id '{first['id']}'"):
        read_manifest(root)


def test_no_manifest_at_all(tmp_path):
    assert manifest_lines(tmp_path) == []
    with pytest.raises(DatasetError, match="no manifest.jsonl"):
        read_manifest(tmp_path)


def test_trail_caps_are_not_counted_as_drops(tiny_dataset, tmp_path):
    """The scene effect "trails" lists each trail's caps after the drops, naming theirs in
    trail_of: drops per frame and drop sizes count the drops only."""
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    path = root / "manifest.jsonl"
    records = [json.loads(x) for x in path.read_text().splitlines()]
    drop = {"center_cm": [0.0, 0.0], "footprint_radius_cm": 0.3}
    cap = {"center_cm": [0.0, -0.4], "footprint_radius_cm": 0.05, "trail_of": 0}
    for r in records:
        r["drops"] = [drop, cap, cap]
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    s = dataset_stats.summarize(root)
    assert s["drops_per_frame"]["mean"] == 1
    assert s["drops_per_frame"]["p95"] == 1


def test_statistics_nothing_recorded_are_null_in_json_and_a_dash_in_the_table(tiny_dataset, capsys):
    """A set whose records hold no dark band or off-frame fraction (older renders, the tiny
    fixture): those statistics are JSON's null, not NaN (not JSON), and '-' in the table, with no
    numpy warning about empty slices."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = dataset_stats.summarize(tiny_dataset)
        assert dataset_stats.main([str(tiny_dataset), "--json"]) == 0
    missing = [k for k, v in s.items() if isinstance(v, dict) and v.get("mean") is None]
    assert missing, "the fixture was meant to lack some statistic"
    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")
    rows = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert rows[0][missing[0]] == {"mean": None, "p5": None, "p95": None}
    assert dataset_stats.main([str(tiny_dataset)]) == 0
    assert "| - |" in capsys.readouterr().out


def test_a_record_cut_short_at_the_end_is_not_read(tiny_dataset, tmp_path):
    """A run interrupted mid-append (a full disk) leaves its last record without its line break:
    the renderer ignores it and renders that sample again, and so do the readers here, instead
    of failing on JSON cut in half."""
    root = tmp_path / "ds"
    shutil.copytree(tiny_dataset, root)
    lines = (root / "manifest.jsonl").read_text().splitlines()
    (root / "manifest.jsonl").write_text("".join(x + "\n" for x in lines[:-1]) + lines[-1][: len(lines[-1]) // 2])
    assert [text for _, _, text in manifest_lines(root)] == lines[:-1]
    assert len(read_manifest(root)) == len(lines) - 1
    # A whole last record without its line break (written by hand) is read, as the renderer reads it.
    (root / "manifest.jsonl").write_text("".join(x + "\n" for x in lines[:-1]) + lines[-1])
    assert [text for _, _, text in manifest_lines(root)] == lines
    # A middle line cut short is no interrupted append: still an error.
    (root / "manifest.jsonl").write_text(lines[0][:20] + "\n" + "".join(x + "\n" for x in lines[1:]))
    with pytest.raises(DatasetError):
        read_manifest(root)
