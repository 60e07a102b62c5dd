"""The trade-off table's pieces: the Pareto front and reading raindrop-bench's table."""

from __future__ import annotations

from raindrop_tools.tradeoffs import pareto, time_rows


def test_pareto_keeps_exactly_the_undominated_points():
    # (ms, PSNR): (10, 30) and (50, 40) and (100, 41) are the front; (60, 35) is dominated by
    # (50, 40); (10, 29) by (10, 30); (100, 41) stays although slow.
    pts = [(10, 30), (50, 40), (60, 35), (10, 29), (100, 41)]
    assert sorted(pareto(pts)) == [0, 1, 4]
    assert pareto([(1, 1)]) == [0]


# raindrop-bench remove's time table as it prints it (tests/CMakeLists.txt's bench_remove_quick
# runs the program and checks the same header).
BENCH_OUTPUT = """## raindrop-remove: time per image

Machine: AMD EPYC, 2 hardware threads; ...

| models | size (WxH) | scale | threads | tiles | edge | RDN | threshold+dilation | 3RN | blend | RFN | other | total | median total | first run |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
| compact (compact) | 512x256 | 1 | 2 | 1 | 0.4 | 70.2 | 0.1 | 100.8 | 0.1 | 10.6 | 1.2 | 115.9 | 116.7 | 180.3 |
| compact (compact) | 2048x1024 | 0.25 | 2 | 1 | 3.0 | 70.0 | 0.1 | 99.0 | 0.1 | 10.0 | 20.0 | 200.0 | 201.5 | 260.0 |

"first run": the first Remover::run on that size ...

## raindrop-remove: GFLOP/s

| models | size (WxH) | threads | GFLOP | RDN GFLOP/s | 3RN GFLOP/s | RFN GFLOP/s | overall GFLOP/s |
|---|---|---|---|---|---|---|---|
| compact (compact) | 512x256 | 2 | 14.21 | 81.2 | 58.2 | 250.3 | 122.6 |
"""


def test_bench_rows_are_read_by_column_title():
    rows = time_rows(BENCH_OUTPUT)
    assert [r["size (WxH)"] for r in rows] == ["512x256", "2048x1024"]  # not the GFLOP/s table's row
    assert rows[0]["median total"] == "116.7" and rows[0]["first run"] == "180.3"
    assert rows[1]["scale"] == "0.25" and rows[1]["threads"] == "2" and rows[1]["tiles"] == "1"


def test_labels_of_points_at_the_same_accuracy_are_stacked():
    from raindrop_tools.tradeoffs import label_offsets

    assert label_offsets([(80.0, 31.0), (100.0, 31.002), (500.0, 31.2)], dy=9.0) == [(5.0, 4.0), (5.0, 13.0), (5.0, 4.0)]


def test_no_models_found_keeps_the_last_tables(tmp_path, monkeypatch, capsys):
    """Run where no model folder exists (outside the repository), it wrote empty tables over
    the last run's and exited 0; --plot-only without a table was a traceback."""
    from raindrop_tools import tradeoffs as T

    out = tmp_path / "tr"
    out.mkdir()
    (out / "tradeoffs.json").write_text("[1]\n")
    (out / "tradeoffs.md").write_text("last run\n")
    monkeypatch.chdir(tmp_path)
    assert T.main(["--out", str(out)]) == 2
    assert "none of the model folders exist here" in capsys.readouterr().err
    assert (out / "tradeoffs.json").read_text() == "[1]\n" and (out / "tradeoffs.md").read_text() == "last run\n"
    assert T.main(["--out", str(tmp_path / "none"), "--plot-only"]) == 2
    assert not (tmp_path / "none").exists()


def test_a_missing_bench_or_no_runs_is_one_line(tmp_path, monkeypatch, capsys):
    """A missing --bench was a FileNotFoundError traceback, --runs 0 a CalledProcessError."""
    from helpers import REPO
    from raindrop_tools import tradeoffs as T

    monkeypatch.chdir(REPO)  # where the model folders are
    assert T.main(["--bench", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "no such program" in capsys.readouterr().err
    assert T.main(["--runs", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--runs must be at least 1" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
