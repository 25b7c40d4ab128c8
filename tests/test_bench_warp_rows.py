"""tools/bench_warp.py's rows: every row run several times is reported by its run of median
ratio, with the ratios of all its runs; the largest scene a memory holds; and the figures
measured alike on both sides of a bed (the tool itself needs warp-lang, a benchmark-only extra;
these tests need none of it)."""

import numpy as np
import pytest

from tools.bench_warp import median_rows


def layer(ratio, n=1000):
    return {"row": "layer", "particles": n, "tai_coll": {"rate": ratio * 1e8}, "warp": {"rate": 1e8},
            "ratio": ratio}


def bed(method, ratio_to_best, n=1000):
    return {"row": "bed", "particles": n, "method": method, "ratio_to_best": ratio_to_best,
            "tai_coll": {"rate": ratio_to_best}, "warp": {}, "ratio": {}, "warp_best": "pbd"}


def test_a_row_run_three_times_reports_its_median_run_and_every_ratio():
    rows = median_rows([layer(1.2), layer(1.6), layer(1.4)])
    assert len(rows) == 1
    row = rows[0]
    assert row["ratio"] == 1.4 and row["tai_coll"]["rate"] == 1.4e8  # the median run itself, not a mix
    assert row["runs"] == [1.2, 1.6, 1.4]  # in the order run
    assert row["ratio_range"] == [1.2, 1.6]


def test_an_even_count_reports_the_lower_middle_run():
    row, = median_rows([layer(2.0), layer(1.0), layer(1.5), layer(1.8)])
    assert row["ratio"] == 1.5


def test_rows_are_kept_apart_by_kind_size_and_method_and_bed_rows_by_their_ratio_to_warps_best():
    runs = [layer(1.1), bed("gauss-seidel", 0.9), bed("jacobi", 0.5), layer(1.1, n=10),
            layer(1.3), bed("gauss-seidel", 0.7), bed("jacobi", 0.6), layer(1.2, n=10),
            layer(1.2), bed("gauss-seidel", 0.8), bed("jacobi", 0.4), layer(1.0, n=10)]
    rows = {(r["row"], r["particles"], r.get("method")): r for r in median_rows(runs)}
    assert set(rows) == {("layer", 1000, None), ("layer", 10, None), ("bed", 1000, "gauss-seidel"),
                         ("bed", 1000, "jacobi")}
    assert rows["layer", 1000, None]["ratio"] == 1.2
    assert rows["layer", 10, None]["ratio"] == 1.1
    assert rows["bed", 1000, "gauss-seidel"]["ratio_to_best"] == 0.8
    assert rows["bed", 1000, "jacobi"]["runs"] == [0.5, 0.6, 0.4]


def test_a_single_run_is_reported_as_it_was():
    run = layer(1.63)
    row, = median_rows([run])
    assert {k: row[k] for k in run} == run and row["runs"] == [1.63] and row["ratio_range"] == [1.63, 1.63]


def test_the_largest_scene_in_memory_is_bounded_by_bytes_and_by_what_32_bit_offsets_index():
    from tai_coll.neighbors.hash_grid import MAX_LISTED
    from tai_coll.scene.particles import MAX_STORED
    from tools.bench_warp import largest_scene

    layer_fit = largest_scene(88.0, 80.0, pairs=False)  # 80 GB at 88 B: 909,090,909 particles by memory,
    assert layer_fit["particles"] == MAX_STORED == 357_913_941  # more than the particle arrays can index
    assert layer_fit["by_memory"] == 909_090_909 and "particle arrays" in layer_fit["limit"]
    assert largest_scene(88.0, 20.0, pairs=False) == {"particles": 227_272_727, "limit": "memory",
                                                      "by_memory": 227_272_727, "memory_gb": 20.0}
    bed_fit = largest_scene(484.0, 80.0, pairs=True)  # 165M by memory, more than the lists can index
    assert bed_fit["particles"] == MAX_LISTED == 44_739_242
    assert bed_fit["by_memory"] == 165_289_256 and "offsets" in bed_fit["limit"]
    small = largest_scene(484.0, 8.0, pairs=True)  # 8 GB: memory is the limit again
    assert small["particles"] == 16_528_925 and small["limit"] == "memory"
    assert small["particles"] * 484.0 <= 8e9 < (small["particles"] + 1) * 484.0


def test_a_beds_contacts_are_its_overlap_and_touching_pairs_a_particle_measured_alike_on_both_sides():
    from tools.bench_warp import R, contacts, overlap_of
    # three in a row, 1.9 R apart: two pairs overlapping by 0.1 R, the ends 3.8 R apart not touching
    x = np.array([[0.0, 0.0, 0.0], [1.9 * R, 0.0, 0.0], [3.8 * R, 0.0, 0.0]]) + 0.1
    measured = contacts(overlap_of(x), len(x))
    assert measured["mean_overlap"] == pytest.approx(0.1, rel=1e-4)
    assert measured["touching_per_particle"] == pytest.approx(2 / 3)
    apart = contacts(overlap_of(x * np.array([1.1, 1.0, 1.0])), len(x))
    assert apart == {"mean_overlap": 0.0, "touching_per_particle": 0.0}


def test_cpu_time_a_particle_step_counts_every_particle_and_step():
    from tools.bench_warp import work
    assert work(2.0, 1000, 100)["cpu_ns_per_particle_step"] == pytest.approx(20_000.0)
