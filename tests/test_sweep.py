"""Parameter sweeps on Ray (tai_coll.sweeps, `tai-coll sweep`): the grid, the rows, failures
recorded while the others finish, an existing cluster by address, the contact sheet.
Ray keeps to 2 CPUs and a few frames here."""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tai_coll as tc
from tai_coll import cli
from tai_coll import sweeps
from tai_coll.sweeps import command, worker

G = 9.81
RADIUS = 0.01

# One particle dropped from `height` (its bottom above the floor) onto a plane of the given
# restitution; 40 substeps a frame at 60 frames/s. metrics() reads the speed it left the floor
# with, from the last frame's state: in free flight v^2 + 2 g y is constant, so
# v_after = sqrt(v^2 + 2 g y) with y the bottom's height (closed form: e sqrt(2 g h)).
DROP_SCRIPT = '''
import numpy as np
import tai_coll as tc
from tai_coll.render import Camera

FRAMES = 11

def scene(restitution=0.5, height=0.1):
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 2400.0, substeps=40)
    s.add_collider(tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)),
                   material=tc.Material(restitution=restitution, friction=0.0))
    s.add_particles(positions=[[0.0, height + 0.01, 0.0]], radius=0.01)
    return s

def metrics(scene):
    y = float(scene.positions()[0, 1]) - 0.01
    vy = float(scene.velocities()[0, 1])
    return {"v_after": float(np.sqrt(vy * vy + 2.0 * 9.81 * y))}

def render_settings():
    return {"camera": Camera(position=(0.0, 0.1, 0.4), look_at=(0.0, 0.05, 0.0))}
'''


def drop_scene(restitution=0.5, height=0.1):
    s = tc.Scene(gravity=(0.0, -G, 0.0), dt=1.0 / 2400.0, substeps=40)
    s.add_collider(tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)),
                   material=tc.Material(restitution=restitution, friction=0.0))
    s.add_particles(positions=[[0.0, height + RADIUS, 0.0]], radius=RADIUS)
    return s


def drop_metrics(scene):
    y = float(scene.positions()[0, 1]) - RADIUS
    vy = float(scene.velocities()[0, 1])
    return {"v_after": float(np.sqrt(vy * vy + 2.0 * G * y))}


@pytest.fixture()
def drop_script(tmp_path):
    path = tmp_path / "drop.py"
    path.write_text(DROP_SCRIPT)
    return path


def no_ray_session():
    import ray

    if ray.is_initialized():
        ray.shutdown()


# ----------------------------------------------------------------------------- the grid
def test_values_are_numbers_where_they_are_numbers():
    assert sweeps.parse_param("restitution=0.2,0.5,1") == ("restitution", [0.2, 0.5, 1])
    assert [type(v) for v in sweeps.parse_param("n=3,1e-3,-2, 4 ")[1]] == [int, float, int, int]
    assert sweeps.parse_param("material=steel,rubber")[1] == ["steel", "rubber"]
    assert sweeps.parse_param("x=nan")[1] == ["nan"]


@pytest.mark.parametrize("text, says", [("restitution", "NAME=V1,V2"), ("=1,2", "NAME=V1,V2"),
                                        ("e=", "one or more"), ("e=1,,2", "one or more"),
                                        ("1e=1", "identifier"), ("class=1", "identifier")])
def test_bad_params_are_refused(text, says):
    with pytest.raises(ValueError, match=says):
        sweeps.parse_param(text)


def test_a_name_given_twice_is_refused():
    with pytest.raises(ValueError, match="given twice"):
        sweeps.parse_params(["e=1", "h=2", "e=3"])


def test_every_combination_once_last_fastest():
    runs = sweeps.combinations({"a": [1, 2], "b": ["x", "y", "z"]})
    assert runs == [{"a": a, "b": b} for a in (1, 2) for b in ("x", "y", "z")]
    assert sweeps.layout({"a": [1, 2], "b": ["x", "y", "z"]}) == (2, 3)
    assert sweeps.layout({"a": [1, 2], "b": [1, 2, 3], "c": [0, 1, 2, 3]}) == (6, 4)


@pytest.mark.parametrize("kwargs, error, says", [
    ({"grid": {"restitution": 0.5}}, TypeError, "grid\\['restitution'\\]"),
    ({"grid": {}}, ValueError, "at least one"),
    ({"grid": {"restitution": []}}, ValueError, "empty"),
    ({"grid": {"mass": [1.0]}}, ValueError, "no parameter 'mass'"),
    ({"frames": 0}, ValueError, "frames"),
    ({"workers": 0}, ValueError, "workers"),
    ({"threads": 0}, ValueError, "threads"),
    ({"metrics": "v"}, TypeError, "metrics"),
    ({"arch": "tpu"}, ValueError, "arch"),
    ({"render": (64, 48)}, ValueError, "render needs out"),
])
def test_bad_arguments_are_refused_before_ray_starts(kwargs, error, says):
    import ray

    no_ray_session()
    args = {"grid": {"restitution": [0.5]}, "frames": 1, **kwargs}
    with pytest.raises(error, match=says):
        tc.sweep(drop_scene, args.pop("grid"), args.pop("frames"), **args)
    assert not ray.is_initialized()


def test_a_missing_ray_names_the_extra(monkeypatch, drop_script, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(ImportError, match=r"tai_coll\[sweep\]"):
        tc.sweep(drop_scene, {"restitution": [0.5]}, 1)
    monkeypatch.setattr(command, "ray_missing", lambda: True)
    assert cli.main(["sweep", str(drop_script), "--param", "restitution=0.5", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'tai_coll[sweep]'" in err


def test_cli_refuses_bad_arguments_in_one_line(drop_script, tmp_path, capsys):
    out = str(tmp_path / "o")
    cases = [(["--param", "mass=1,2"], "no parameter 'mass'"),
             (["--param", "restitution"], "NAME=V1,V2"),
             (["--param", "restitution=0.5", "--frames", "0"], "--frames"),
             (["--param", "restitution=0.5", "--workers", "0"], "--workers"),
             (["--param", "restitution=0.5", "--res", "64x48"], "add --render")]
    for extra, says in cases:
        assert cli.main(["sweep", str(drop_script), "--out", out, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and says in err, err
    assert cli.main(["sweep", str(tmp_path / "none.py"), "--param", "e=1"]) == 2
    assert "not found" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- sweeps on Ray
def test_drop_sweep_gives_the_closed_form_bounce_and_records_a_failure(drop_script, tmp_path, capsys):
    """restitution x height: each row's speed off the floor is e sqrt(2 g h); restitution 1.5
    is refused by the scene (its row says why) while the other runs finish; exit 1."""
    no_ray_session()
    out = tmp_path / "sweep"
    code = cli.main(["sweep", str(drop_script), "--param", "restitution=0.5,0.8,1.5", "--param", "height=0.05,0.1",
                     "--frames", "11", "--out", str(out), "--workers", "2", "--arch", "cpu"])
    printed = capsys.readouterr().out
    assert code == 1
    rows = sweeps.read_results(out / "results.csv")
    assert [(r["restitution"], r["height"]) for r in rows] == [(e, h) for e in (0.5, 0.8, 1.5) for h in (0.05, 0.1)]
    for row in rows:
        assert row["pid"] != os.getpid() and row["node"]
        assert row["wall_time"] > 0
        if row["restitution"] > 1:
            assert row["status"].startswith("ValueError") and "restitution" in row["status"]
            assert row["v_after"] is None
        else:
            assert row["status"] == "ok"
            expected = row["restitution"] * np.sqrt(2 * G * row["height"])
            assert row["v_after"] == pytest.approx(expected, rel=0.01)
    assert json.loads((out / "results.json").read_text()) == [
        {k: (None if v == "" else v) for k, v in r.items()} for r in rows]
    assert "6 runs of 11 frames, 4 ok, 2 failed" in printed


def test_python_api_returns_the_rows_run_in_workers():
    no_ray_session()
    rows = tc.sweep(drop_scene, {"restitution": [0.6, 0.9], "height": [0.08]}, 11, metrics=drop_metrics,
                    workers=2, arch="cpu", progress=False)
    assert [r["run"] for r in rows] == [0, 1]
    for row, e in zip(rows, (0.6, 0.9)):
        assert row["status"] == "ok" and row["pid"] != os.getpid()
        assert row["v_after"] == pytest.approx(e * np.sqrt(2 * G * 0.08), rel=0.01)
    assert set(rows[0]) == {"run", "restitution", "height", "v_after", "wall_time", "pid", "node", "status"}


def failing_metrics(scene):
    return {"v": "fast"}


def test_a_bad_metric_fails_its_run_only():
    no_ray_session()
    rows = tc.sweep(drop_scene, {"height": [0.05, 0.1]}, 2, metrics=failing_metrics, workers=2, arch="cpu",
                    progress=False)
    assert all(r["status"] == "TypeError: metrics()['v'] must be a number; got str" for r in rows)


def test_a_non_finite_state_is_a_failure():
    class State:
        num_particles = 2

        def positions(self):
            return np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])

        def velocities(self):
            return np.zeros((2, 3))

    with pytest.raises(RuntimeError, match="non-finite state after the last frame: 1 particle"):
        worker.check_state(State())


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_same_sweep_on_a_cluster_by_address(drop_script, tmp_path, capsys):
    """`ray start --head` on 127.0.0.1, then --address: the runs go to that cluster's workers."""
    no_ray_session()
    ray_cli = str(Path(sys.executable).with_name("ray"))
    port = free_port()
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    started = subprocess.run([ray_cli, "start", "--head", f"--port={port}", "--node-ip-address=127.0.0.1",
                              "--num-cpus=2", "--include-dashboard=false", "--disable-usage-stats"],
                             capture_output=True, text=True, env=env, timeout=120)
    assert started.returncode == 0, started.stderr
    try:
        out = tmp_path / "cluster"
        code = cli.main(["sweep", str(drop_script), "--param", "restitution=0.5,0.8", "--param", "height=0.1",
                         "--frames", "11", "--out", str(out), "--address", f"127.0.0.1:{port}", "--arch", "cpu"])
        assert code == 0, capsys.readouterr().err
        rows = sweeps.read_results(out / "results.csv")
        assert [r["status"] for r in rows] == ["ok", "ok"]
        for row in rows:
            assert row["pid"] != os.getpid()
            assert row["v_after"] == pytest.approx(row["restitution"] * np.sqrt(2 * G * 0.1), rel=0.01)
    finally:
        subprocess.run([ray_cli, "stop", "--force"], capture_output=True, env=env, timeout=120)


@pytest.mark.skipif(os.environ.get("TAI_COLL_SKIP_RENDER_TESTS") == "1", reason="TAI_COLL_SKIP_RENDER_TESTS=1")
def test_render_writes_a_contact_sheet_of_the_grid(drop_script, tmp_path):
    """2 x 3 runs at 64x48: a sheet of 2 rows and 3 columns of frames, the failed run grey."""
    from PIL import Image

    no_ray_session()
    out = tmp_path / "render"
    code = cli.main(["sweep", str(drop_script), "--param", "restitution=0.5,1.5", "--param", "height=0.05,0.1,0.2",
                     "--frames", "2", "--out", str(out), "--workers", "2", "--arch", "cpu", "--render",
                     "--res", "64x48"])
    assert code == 1  # restitution 1.5 fails
    rows = sweeps.read_results(out / "results.csv")
    frames = [out / r["frame_png"] for r in rows if r["status"] == "ok"]
    assert len(frames) == 3 and all(Image.open(f).size == (64, 48) for f in frames)
    sheet = np.asarray(Image.open(out / "contact_sheet.png").convert("RGB"))
    assert sheet.shape == (2 * 48, 3 * 64, 3)
    failed_tile = sheet[48 + 40:, :64]  # below its label band
    assert np.all(failed_tile == sweeps.sheet.FAILED_GREY)
    assert sheet[:48, :64].std() > 1.0  # a rendered frame, not a blank tile
