"""Every scene script runs headless for its frames and passes its own physical check."""

import importlib.util
from pathlib import Path

import pytest

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
