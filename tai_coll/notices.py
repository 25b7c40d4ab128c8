"""Warnings that point at the user's code.

A warning raised deep in tai_coll (a scene's step, through the runtime guard's wrapper, the
solver and its checks) names the line that warnings.warn's `stacklevel` counts up to; a fixed
count breaks whenever a call path gains or loses a frame. `warn` counts instead: it names the
first caller outside the tai_coll package (a user's script, a scene file, a test).
"""

import sys
import warnings


def _inside(frame) -> bool:
    name = frame.f_globals.get("__name__", "")
    return name == "tai_coll" or name.startswith("tai_coll.")


def warn(message: str, category: type = RuntimeWarning):
    """warnings.warn(message, category) attributed to the first caller outside tai_coll."""
    level = 2  # stacklevel 2 is the caller of this function
    frame = sys._getframe(1)
    while frame.f_back is not None and _inside(frame):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)
