"""The parameter grid of a sweep: `NAME=V1,V2,...` options parsed, checked against the scene
function's signature, and expanded into every combination (the cartesian product)."""

import inspect
import itertools
import keyword
import math
import numbers


def parse_value(text: str):
    """A value as written on the command line: an int where it is one ("3", "-2"), else a
    float where it is one ("0.5", "1e-3"), else the text itself ("steel")."""
    text = text.strip()
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value if math.isfinite(value) else text  # "nan", "inf": names more likely than numbers


def parse_param(text: str) -> tuple:
    """`NAME=V1,V2,...` -> (NAME, [values]); ValueError saying what is wrong."""
    name, sep, values = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise ValueError(f"--param must read NAME=V1,V2,...; got {text!r}")
    check_name(name, "--param")
    parts = [part.strip() for part in values.split(",")]
    if not values.strip() or any(not part for part in parts):
        raise ValueError(f"--param {name}: give one or more comma-separated values (NAME=V1,V2,...); got {text!r}")
    return name, [parse_value(part) for part in parts]


def parse_params(texts) -> dict:
    """Repeated --param options -> {name: [values]} in the order given; a name given twice
    is a ValueError."""
    grid = {}
    for text in texts:
        name, values = parse_param(text)
        if name in grid:
            raise ValueError(f"--param {name} is given twice: list all its values in one option")
        grid[name] = values
    return grid


def check_name(name, what: str):
    if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
        raise ValueError(f"{what}: a parameter name must be a Python identifier; got {name!r}")


def check_grid(grid) -> dict:
    """A copy of `grid` ({name: sequence of values}) with lists for values; TypeError or
    ValueError naming the argument when it is not one."""
    if not isinstance(grid, dict):
        raise TypeError(f"grid must be a dict of parameter name -> list of values; got {type(grid).__name__}")
    if not grid:
        raise ValueError("grid must name at least one parameter")
    checked = {}
    for name, values in grid.items():
        check_name(name, "grid")
        if isinstance(values, (str, bytes)) or not isinstance(values, (list, tuple, range)) and not (
                hasattr(values, "__len__") and hasattr(values, "__iter__")):
            raise TypeError(f"grid[{name!r}] must be a list of values; got {type(values).__name__}")
        values = [v.item() if hasattr(v, "item") and not isinstance(v, (str, bytes)) else v for v in values]
        if not values:
            raise ValueError(f"grid[{name!r}] is empty: give at least one value")
        checked[name] = values
    return checked


def check_signature(scene_fn, names, what: str = "scene()"):
    """ValueError unless scene_fn accepts every name as a keyword argument."""
    try:
        signature = inspect.signature(scene_fn)
    except (TypeError, ValueError):
        return  # a builtin or C callable: let the call tell
    parameters = signature.parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        return
    takes = [n for n, p in parameters.items()
             if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)]
    unknown = [n for n in names if n not in takes]
    if unknown:
        accepted = ", ".join(takes) if takes else "none"
        raise ValueError(f"{what} has no parameter {', '.join(map(repr, unknown))} (its parameters: {accepted})")


def combinations(grid: dict) -> list:
    """Every combination of the grid's values, one dict per run: the last parameter varies
    fastest (itertools.product order)."""
    names = list(grid)
    return [dict(zip(names, values)) for values in itertools.product(*(grid[n] for n in names))]


def is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)
