"""report_file.py: where a --json report may go (no torch)."""

import json

from raindrop_tools.report_file import report_path_problem, write_report
from raindrop_tools.score_outputs import main as score_main


def test_a_report_goes_only_to_a_new_json_file_or_an_earlier_report(tmp_path):
    (tmp_path / "manifest.jsonl").write_text('{"id": "a"}\n')
    (tmp_path / "img.json").write_bytes(b"\x89PNG\r\n")
    (tmp_path / "old.json").write_text('{"mean": 1}\n')
    (tmp_path / "list.json").write_text("[1, 2]\n")
    (tmp_path / "d.json").mkdir()
    assert "name the report .json" in report_path_problem(tmp_path / "manifest.jsonl")
    assert "not an earlier report" in report_path_problem(tmp_path / "img.json")
    assert "not an earlier report" in report_path_problem(tmp_path / "list.json")
    assert "not a plain file" in report_path_problem(tmp_path / "d.json")
    assert report_path_problem(tmp_path / "old.json") is None
    assert report_path_problem(tmp_path / "new" / "r.json") is None
    write_report(tmp_path / "new" / "r.json", {"x": 1})
    assert json.loads((tmp_path / "new" / "r.json").read_text()) == {"x": 1}
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["r.json"]


def test_score_outputs_refuses_a_report_over_a_data_file_before_scoring(tmp_path, capsys):
    manifest = tmp_path / "manifest.jsonl"
    manifest.write_text('{"id": "a"}\n')
    assert score_main(["--data", str(tmp_path / "nothing"), "--outputs", str(tmp_path), "--json", str(manifest)]) == 2
    assert "name the report .json" in capsys.readouterr().err
    assert manifest.read_text() == '{"id": "a"}\n'
