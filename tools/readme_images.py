"""The README's pictures: three small frames of each scene, side by side, in docs/images/.

    python tools/readme_images.py                      # every scene in scenes/
    python tools/readme_images.py bouncing_balls moving_paddle --size 320x180

Each scene script runs for its FRAMES (or 60) on the CPU; frames at one sixth, one half and
the end of the run go into docs/images/NAME.png: the README's gallery, a few small strips
kept in git (every other render goes to ignored folders).
"""

import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def load(path: Path):
    spec = importlib.util.spec_from_file_location(f"readme_scene_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def strip(path: Path, width: int, height: int) -> np.ndarray:
    from tai_coll.render import Renderer

    module = load(path)
    scene = module.scene()
    settings = module.render_settings() if hasattr(module, "render_settings") else {}
    settings.pop("width", None), settings.pop("height", None)
    renderer = Renderer(width=width, height=height, **settings)
    frames = int(getattr(module, "FRAMES", 60))
    keep = sorted({max(1, frames // 6), max(1, frames // 2), frames})
    renderer.camera_for(scene)  # framed on the first state, as `tai-coll run` frames it
    images = []
    for k in range(1, frames + 1):
        scene.step()
        if k in keep:
            images.append(renderer.render(scene))
    gap = np.full((height, 4, 3), 255, dtype=np.uint8)
    return np.concatenate([part for image in images for part in (image, gap)][:-1], axis=1)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", help="scene names (default: every scenes/*.py)")
    parser.add_argument("--size", default="320x180", help="size of each frame (default 320x180)")
    parser.add_argument("--out", default=str(ROOT / "docs" / "images"))
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))

    import tai_coll as tc
    from tai_coll.render import write_png

    tc.init(arch="cpu")
    names = args.scenes or [p.stem for p in sorted((ROOT / "scenes").glob("*.py"))]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        path = ROOT / "scenes" / f"{name}.py"
        if not path.is_file():
            print(f"no scene {path}", file=sys.stderr)
            return 2
        target = write_png(out / f"{name}.png", strip(path, width, height))
        print(f"wrote {target.relative_to(ROOT) if target.is_relative_to(ROOT) else target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
