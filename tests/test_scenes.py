"""Every scene script runs headless for its frames and passes its own physical check."""

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import tai_coll as tc

ROOT = Path(__file__).resolve().parents[1]

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.py"))
HEAVY = {"avalanche", "random_pour"}  # a minute or more on their own (thousands of particles, in contact): slow


def load(path: Path):
    spec = importlib.util.spec_from_file_location(f"scene_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem, marks=[pytest.mark.slow] if p.stem in HEAVY else [])
                                  for p in SCENES])
def test_scene_script(path):
    module = load(path)
    scene = module.scene()
    assert scene.num_particles > 0 or scene.emitters
    module.main()  # builds, runs and checks the physics; raises AssertionError on failure


def restart_runtime():
    """End this process's Taichi runtime and start the same one again (conftest's settings):
    ending it writes what it compiled to the offline cache."""
    info = tc.runtime.info()
    settings = dict(arch=info.requested_arch, precision=info.precision, threads=info.threads)
    tc.init(**settings, seed=info.seed + 1)
    tc.init(**settings, seed=info.seed)


@pytest.mark.slow
def test_a_users_pytest_run_of_scenes_shows_no_syntax_warning(tmp_path):
    # A user's own test file, run by pytest in a fresh process with SyntaxWarnings as errors:
    # every scene script, and every solver path with particle pairs (Gauss-Seidel, Jacobi,
    # DEM with springs, spin and Verlet lists). Taichi transforms a kernel's source, where
    # it would warn, in every process that launches it; the runtime's settings are the
    # suite's. It runs after the scenes above: restarting this process's runtime writes the
    # kernels they compiled to Taichi's offline cache (Taichi writes it when a runtime ends),
    # so the fresh process loads them instead of compiling them again (342 s on a cold cache).
    restart_runtime()
    (tmp_path / "test_user.py").write_text(textwrap.dedent(f"""
        import importlib.util
        from pathlib import Path

        import numpy as np
        import tai_coll as tc

        SCENES = Path({str(ROOT / "scenes")!r})

        def test_scenes_run():
            tc.init(arch="cpu", precision="f64", threads=2, seed=0)
            for path in sorted(SCENES.glob("*.py")):
                spec = importlib.util.spec_from_file_location(path.stem, path)
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                module.scene().step(1)
            rng = np.random.default_rng(0)
            cases = [(tc.ImpulseSolver(), {{}}), (tc.ImpulseSolver(), dict(method="jacobi")),
                     (tc.PenaltySolver(hertz=200.0, spin=True), dict(tangential_springs=True, verlet_skin=0.005)),
                     (tc.PenaltySolver(hertz=200.0), {{}})]
            for solver, options in cases:
                s = tc.Scene(dt=1e-4, substeps=2, solver=solver)
                s.add_collider(tc.Plane())
                s.enable_particle_collisions(**options)
                s.add_particles(positions=rng.uniform(-0.05, 0.05, (100, 3)) + (0.0, 0.1, 0.0), radius=0.005)
                s.step(2)
                assert s.particle_overlap()["pairs"] >= 0
        """))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-W",
                           "error::SyntaxWarning", str(tmp_path / "test_user.py")], cwd=tmp_path,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "SyntaxWarning" not in done.stdout + done.stderr
