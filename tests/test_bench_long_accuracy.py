"""benchmarks/bench_long_accuracy.py's comparison (docs/performance.md's long-chain accuracy table): the
worst relative difference, which station and metric it is, and the table against the reference, on
made-up runs (the runs themselves take minutes: `python benchmarks/bench_long_accuracy.py`)."""

import pytest

from benchmarks import bench_long_accuracy as bench


def test_the_worst_difference_is_relative_and_says_where():
    reference = [[1.0, 2.0], [4.0, 10.0]]
    values = [[1.001, 2.0], [4.0, 10.05]]
    worst, station, metric = bench.worst_difference(values, reference)
    assert worst == pytest.approx(5e-3)
    assert (station, metric) == (1, 1)


def test_the_table_compares_every_variant_with_the_reference(monkeypatch):
    stations = ["drive-end", "slack-side"]
    reference = [[1.0, 1.0, 1.0, 1.0, 1.0], [2.0, 2.0, 2.0, 2.0, 2.0]]
    off = [[1.0, 1.0, 1.0, 1.0, 1.0], [2.0, 2.0, 2.006, 2.0, 2.0]]

    def run(n, variant, keep):  # the pipeline's and the sampled metrics the same here
        values = reference if variant == "tight-10" else off
        summary = {
            "variant": variant,
            "cpu_s": 1.5,
            "cycles": 13,
            "residual": 4.2e-5,
            "steps_per_output": 21,
            "stations": stations,
        }
        return {**summary, "pipeline": values, "sampled": values}

    monkeypatch.setattr(bench, "_in_subprocess", run)
    lines = bench.table(2000, ["default"], "tight-10")
    assert lines[0] == "2000 links, against tight-10 (safety / 10, tol 1e-08, damping 1e-07)"
    assert lines[4].startswith("| tight-10 | 0.00e+00 ")
    cell = "3.00e-03 (rms_acceleration_m_s2, slack-side)"
    assert lines[2].startswith("| variant | pipeline's station metrics: worst | sampled metrics: worst | CPU |")
    assert lines[5] == f"| default | {cell} | {cell} | 1.5 s | 13 (4.2e-05) | 21 |"
    lines = bench.table(10000, ["default"], "search-tol")  # where no tight run is affordable
    assert lines[0] == "10000 links, against search-tol (a variant of the default run, no tight run)"


def test_a_kept_run_is_read_back_not_run_again(tmp_path, monkeypatch):
    (tmp_path / "2000-default.json").write_text('{"cycles": 7}')

    def no_run(*args, **kwargs):
        raise AssertionError("a kept run was run again")

    monkeypatch.setattr(bench.subprocess, "run", no_run)
    assert bench._in_subprocess(2000, "default", tmp_path) == {"cycles": 7}
    with pytest.raises(AssertionError, match="run again"):
        bench._in_subprocess(2000, "tight-5", tmp_path)


def test_an_unknown_variant_is_named():
    with pytest.raises(SystemExit, match="--variants: unknown no-such; expected some of tight-3.5, tight-5, tight-10"):
        bench.main(["--variants", "default", "no-such"])
