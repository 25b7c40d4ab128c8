"""The benchmark tools refuse a report path they could not write before anything runs (a
benchmark that ran for minutes and then could not write its JSON would lose its figures), and
leave nothing half-written when writing fails."""

import json

import pytest

from tools import bench, bench_bodies, bench_render, bench_warp, bench_workflow, pile_settle

TOOLS = [(bench.main, "--json", ["--quick"]), (bench_bodies.main, "--out", []), (bench_render.main, "--json", []),
         (bench_warp.main, "--out", []), (bench_workflow.main, "--out", []), (pile_settle.main, "--json", [])]
NAMES = [main.__module__.split(".")[-1] for main, _option, _extra in TOOLS]


@pytest.mark.parametrize("main, option, extra", TOOLS, ids=NAMES)
def test_a_report_path_that_is_a_directory_is_refused_naming_the_option(main, option, extra, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main([*extra, option, str(tmp_path)])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert option in err and "is a directory" in err
    assert list(tmp_path.iterdir()) == []  # nothing written beside it either


@pytest.mark.parametrize("main, option, extra", TOOLS, ids=NAMES)
def test_a_report_path_under_a_file_is_refused_naming_the_option(main, option, extra, tmp_path, capsys):
    blocker = tmp_path / "results"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit) as stop:
        main([*extra, option, str(blocker / "deeper" / "report.json")])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert option in err and "is a file" in err
    assert blocker.read_text() == "not a folder" and sorted(p.name for p in tmp_path.iterdir()) == ["results"]


def test_bench_render_refuses_a_resolution_it_cannot_read(tmp_path, capsys):
    for res in ("1280", "1280x", "0x720", "wide"):
        with pytest.raises(SystemExit) as stop:
            bench_render.main(["--res", res, "--json", str(tmp_path / "render.json")])
        assert stop.value.code == 2 and "--res" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_report_is_written_whole_or_not_at_all(tmp_path):
    path = bench.write_json(tmp_path / "sub" / "report.json", {"rate": 1.5e8, "rows": [1, 2]})
    assert json.loads(path.read_text()) == {"rate": 1.5e8, "rows": [1, 2]}
    assert sorted(p.name for p in path.parent.iterdir()) == ["report.json"]  # the temporary file moved
    with pytest.raises(TypeError):
        bench.write_json(tmp_path / "bad.json", {"rate": object()})  # not JSON: nothing left behind
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub"]
    (tmp_path / "taken").mkdir()
    with pytest.raises(OSError):
        bench.write_json(tmp_path / "taken", {"rate": 1.0})  # a folder in the way of the move
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub", "taken"]


@pytest.mark.parametrize("main, argv, option", [
    (bench.main, ["--frames", "0"], "--frames"),
    (bench.main, ["--threads", "two"], "--threads"),
    (bench.main, ["--pile-only", "--pile-seconds", "0"], "--pile-seconds"),
    (bench.main, ["--pile-only", "--pile-seconds-1m", "nan"], "--pile-seconds-1m"),
    (bench_bodies.main, ["--particles", "0"], "--particles"),
    (bench_workflow.main, ["--frames", "-1"], "--frames"),
    (bench_render.main, ["--threads", "0"], "--threads"),
    (bench_warp.main, ["--layer-frames", "0"], "--layer-frames"),
    (bench_warp.main, ["--repeats", "0"], "--repeats"),
    (bench_warp.main, ["--timed", "5"], "--timed"),
    (bench_warp.main, ["--timed", "105"], "--timed"),
    (bench_warp.main, ["--settle", "15"], "--settle"),
    (bench_warp.main, ["--settle", "-10"], "--settle"),
    (pile_settle.main, ["--threads", "0"], "--threads"),
    (pile_settle.main, ["--particles", "0"], "--particles"),
    (pile_settle.main, ["--every", "0"], "--every"),
    (pile_settle.main, ["--seconds", "nan"], "--seconds"),
    (pile_settle.main, ["--lattice", "0"], "--lattice"),
    (bench_warp.main, ["--arch", "vulkan"], "--arch"),
    (bench_warp.main, ["--rows", "layer,beds"], "--rows"),
    (bench_warp.main, ["--rows", ","], "--rows"),
    (bench_warp.main, ["--memory-gb", "0"], "--memory-gb"),
    (bench_warp.main, ["--memory-gb", "inf"], "--memory-gb"),
    (bench_warp.main, ["--memory-gb", "lots"], "--memory-gb"),
    (bench_bodies.main, ["--arch", "gpu0"], "--arch"),
    (bench_workflow.main, ["--arch", "tpu"], "--arch"),
], ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_counts_and_times_a_tool_cannot_run_are_refused_naming_the_option(main, argv, option, tmp_path, capsys):
    report = "--json" if main in (bench.main, bench_render.main, pile_settle.main) else "--out"
    with pytest.raises(SystemExit) as stop:
        main([*argv, report, str(tmp_path / "report.json")])
    assert stop.value.code == 2
    assert option in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
