"""A sweep's table: results.csv and results.json, one row per run, written atomically."""

import csv
import json
import math

from ..export import atomic_write


def columns(rows: list) -> list:
    """Every key of every row, in the order first seen (runs that failed have no metrics)."""
    seen = {}
    for row in rows:
        for key in row:
            seen.setdefault(key, None)
    return list(seen)


def _json_value(value):
    return None if isinstance(value, float) and not math.isfinite(value) else value


def write_results(folder, rows: list) -> tuple:
    """DIR/results.csv and DIR/results.json; returns their paths. A run's missing column is
    empty in the CSV and null in the JSON; NaN and infinities are null in the JSON."""
    names = columns(rows)

    def write_csv(path):
        with open(path, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=names, restval="")
            writer.writeheader()
            writer.writerows(rows)

    def write_json(path):
        with open(path, "w") as f:
            json.dump([{k: _json_value(row.get(k)) for k in names} for row in rows], f, indent=1)
            f.write("\n")

    return atomic_write(f"{folder}/results.csv", write_csv), atomic_write(f"{folder}/results.json", write_json)


def read_results(path) -> list:
    """results.csv back as dicts, numbers as numbers (a small reader for scripts and tests)."""
    from .grid import parse_value

    with open(path, newline="") as f:
        return [{k: parse_value(v) if v != "" else None for k, v in row.items()} for row in csv.DictReader(f)]
