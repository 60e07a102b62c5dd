"""The trade-off table's pieces: the Pareto front and parsing raindrop-bench's table."""

from __future__ import annotations

from raindrop_tools.tradeoffs import ROW_RE, pareto


def test_pareto_keeps_exactly_the_undominated_points():
    # (ms, PSNR): (10, 30) and (50, 40) and (100, 41) are the front; (60, 35) is dominated by
    # (50, 40); (10, 29) by (10, 30); (100, 41) stays although slow.
    pts = [(10, 30), (50, 40), (60, 35), (10, 29), (100, 41)]
    assert sorted(pareto(pts)) == [0, 1, 4]
    assert pareto([(1, 1)]) == [0]


def test_bench_rows_are_parsed():
    line = "| compact (compact) | 256x512 | 2 | 1 | 0.9 | 20.1 | 0.2 | 21.0 | 0.3 | 10.5 | 1.0 | 54.0 | 53.2 |"
    m = ROW_RE.match(line)
    assert m and m["size"] == "256x512" and m["threads"] == "2" and m["tiles"] == "1"
    cells = [c.strip() for c in m["rest"].split("|") if c.strip()]
    assert float(cells[-1]) == 53.2


def test_labels_of_points_at_the_same_accuracy_are_stacked():
    from raindrop_tools.tradeoffs import label_offsets

    assert label_offsets([(80.0, 31.0), (100.0, 31.002), (500.0, 31.2)], dy=9.0) == [(5.0, 4.0), (5.0, 13.0), (5.0, 4.0)]
