"""Colour maps: values in a range to RGB in [0, 1], on numpy arrays.

viridis and plasma (perceptually uniform, from matplotlib) are stored as eleven samples and
interpolated linearly; turbo uses Google's polynomial fit; coolwarm (diverging, for signed
quantities) is three samples; gray is the identity.
"""

from __future__ import annotations

import numpy as np

_VIRIDIS = [
    (0.267004, 0.004874, 0.329415), (0.282623, 0.140926, 0.457517), (0.253935, 0.265254, 0.529983),
    (0.206756, 0.371758, 0.553117), (0.163625, 0.471133, 0.558148), (0.127568, 0.566949, 0.550556),
    (0.134692, 0.658636, 0.517649), (0.266941, 0.748751, 0.440573), (0.477504, 0.821444, 0.318195),
    (0.741388, 0.873449, 0.149561), (0.993248, 0.906157, 0.143936),
]
_PLASMA = [
    (0.050383, 0.029803, 0.527975), (0.254627, 0.013882, 0.615419), (0.417642, 0.000564, 0.658390),
    (0.562738, 0.051545, 0.641509), (0.692840, 0.165141, 0.564522), (0.798216, 0.280197, 0.469538),
    (0.881443, 0.392529, 0.383229), (0.949217, 0.517763, 0.295662), (0.988260, 0.652325, 0.211364),
    (0.988648, 0.809579, 0.145357), (0.940015, 0.975158, 0.131326),
]
_COOLWARM = [(0.230, 0.299, 0.754), (0.865, 0.865, 0.865), (0.706, 0.016, 0.150)]
_TURBO = np.array([  # rows r, g, b: coefficients of t^0 .. t^5
    [0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943],
    [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604],
    [0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973],
])


def _sampled(table):
    table = np.asarray(table, dtype=np.float64)
    knots = np.linspace(0.0, 1.0, len(table))

    def apply(t):
        return np.column_stack([np.interp(t, knots, table[:, c]) for c in range(3)])

    return apply


def _turbo(t):
    powers = t[:, None] ** np.arange(6)
    return np.clip(powers @ _TURBO.T, 0.0, 1.0)


COLORMAPS = {
    "viridis": _sampled(_VIRIDIS),
    "plasma": _sampled(_PLASMA),
    "turbo": _turbo,
    "coolwarm": _sampled(_COOLWARM),
    "gray": lambda t: np.repeat(t[:, None], 3, axis=1),
}


def check_colormap(name: str) -> str:
    if name not in COLORMAPS:
        raise ValueError(f"colormap must be one of {sorted(COLORMAPS)}; got {name!r}")
    return name


def map_colors(values, name: str, low: float, high: float) -> np.ndarray:
    """(N,) values to (N, 3) float32 RGB: `low` and below get the map's first colour, `high`
    and above its last; NaN gets the middle."""
    check_colormap(name)
    v = np.asarray(values, dtype=np.float64).ravel()
    span = high - low
    t = (v - low) / span if span > 0 else np.full_like(v, 0.5)
    t = np.clip(np.nan_to_num(t, nan=0.5), 0.0, 1.0)
    return np.ascontiguousarray(COLORMAPS[name](t), dtype=np.float32)
