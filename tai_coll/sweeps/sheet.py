"""The contact sheet of a rendered sweep: every run's last frame in one labelled grid.

Layout: the last parameter's values run along the columns, every combination of the others
down the rows (the runs' own order), so a sweep of a x b values is a rows x columns grid.
Tiles keep the frames' size; the sheet is exactly (rows * H, columns * W). Each tile carries
its parameter values on a dark band at its top; a run that failed is a grey tile saying so."""

import numpy as np

FAILED_GREY = 48


def layout(grid: dict) -> tuple:
    """(rows, columns) of the sheet for a grid {name: values}."""
    names = list(grid)
    columns = len(grid[names[-1]])
    rows = 1
    for name in names[:-1]:
        rows *= len(grid[name])
    return rows, columns


def label(params: dict) -> str:
    return "  ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in params.items())


def draw_label(tile: np.ndarray, text: str, failed: bool) -> np.ndarray:
    """The tile with `text` (and "failed") on a dark band along its top (Pillow draws it)."""
    from PIL import Image, ImageDraw, ImageFont

    image = Image.fromarray(tile)
    draw = ImageDraw.Draw(image, "RGBA")
    size = max(10, min(tile.shape[0] // 14, 24))
    font = ImageFont.load_default(size=size)
    lines = [text] + (["failed"] if failed else [])
    band = (size + 4) * len(lines) + 4
    draw.rectangle([0, 0, tile.shape[1], band], fill=(0, 0, 0, 170))
    for k, line in enumerate(lines):
        draw.text((4, 3 + k * (size + 4)), line, font=font, fill=(255, 255, 255, 255) if k == 0 else (255, 120, 90, 255))
    return np.asarray(image.convert("RGB"))


def contact_sheet(frames: list, params: list, grid: dict) -> np.ndarray:
    """The sheet as an (rows * H, columns * W, 3) uint8 array. frames: each run's last frame
    ((H, W, 3) uint8, all the same size) or None for a run that failed, in run order;
    params: each run's parameter dict."""
    rows, columns = layout(grid)
    if len(frames) != rows * columns or len(params) != len(frames):
        raise ValueError(f"the sheet needs {rows * columns} runs ({rows} x {columns}); got {len(frames)}")
    shapes = {f.shape for f in frames if f is not None}
    if len(shapes) > 1:
        raise ValueError(f"the frames differ in size: {sorted(shapes)}")
    if not shapes:
        raise ValueError("no run rendered a frame")
    h, w, _ = shapes.pop()
    sheet = np.empty((rows * h, columns * w, 3), dtype=np.uint8)
    for k, (frame, values) in enumerate(zip(frames, params)):
        tile = frame if frame is not None else np.full((h, w, 3), FAILED_GREY, dtype=np.uint8)
        r, c = divmod(k, columns)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = draw_label(np.ascontiguousarray(tile), label(values),
                                                                 frame is None)
    return sheet
