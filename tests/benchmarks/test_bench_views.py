"""What the in-between benchmark's sequence rows report (benchmarks/bench_inbetween.py, issue 17):
the median of the per-frame ratios beside the ratio of medians, and the ``op`` protocol — the
sequence with the ends the *In-between Frames* operator chooses for the source. Sources are
analytic sheets bending about an axis (no Blender, no timing asserted)."""

import statistics
import types
import warnings

import numpy as np
import pytest

from bench_helpers import grid_bend, steady_bend
from benchmarks import bench_inbetween as bench
from core import retime
from core.sequence_inbetweens import SequenceInterpolator


def rows(errors):
    return [{"rms": e} for e in errors]


def test_the_per_frame_median_and_the_ratio_of_medians_can_disagree():
    # Ours 5 % better than the peer on four frames of five and 5 % worse on the middle one: the
    # medians fall on that frame, so their ratio reads 1.05 while the per-frame median is 0.95.
    peer = [1.0, 2.0, 3.0, 4.0, 5.0]
    ours = [0.95 * 1.0, 0.95 * 2.0, 1.05 * 3.0, 0.95 * 4.0, 0.95 * 5.0]
    assert statistics.median(ours) / statistics.median(peer) == pytest.approx(1.05, rel=1e-12)
    got = bench.per_frame_ratios(rows(ours), rows(peer))
    assert got["median"] == pytest.approx(statistics.median(o / p for o, p in zip(ours, peer)), rel=1e-12)
    assert got["median"] == pytest.approx(0.95, rel=1e-12)
    assert got["max"] == pytest.approx(1.05, rel=1e-12)
    assert (got["above"], got["n"]) == (1, 5)


def test_an_exact_peer_counts_as_a_tie_or_as_infinitely_better():
    got = bench.per_frame_ratios(rows([0.0, 1.0, 2.0]), rows([0.0, 0.0, 1.0]))
    assert got["median"] == 2.0 and got["max"] == np.inf and got["above"] == 2  # ratios 1, ∞, 2
    assert got["p90"] == np.inf  # between 2 and ∞


def per_frame_rms(x, true):
    """RMS over the vertices ÷ the true frame's bounding-box diagonal, computed here apart from
    the benchmark's ``Metrics``."""
    return np.sqrt(((x - true) ** 2).sum(axis=1).mean()) / np.linalg.norm(true.max(axis=0) - true.min(axis=0))


def expected_rows(frames, triangles, g, **options):
    """Per dropped frame of the sequence keyed on every g-th frame: (ours, blend, Catmull–Rom) RMS."""
    keys = frames[: (len(frames) - 1) // g * g + 1: g]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sequence = SequenceInterpolator(keys, triangles, **options)
    out = []
    for k in range(len(keys) - 1):
        predicted = sequence.poses(k, np.arange(1, g) / g)  # a gap's in-betweens together, as the operator asks
        for j in range(1, g):
            s, true = j / g, frames[k * g + j]
            out.append((per_frame_rms(predicted[j - 1], true),
                        per_frame_rms((1 - s) * keys[k] + s * keys[k + 1], true),
                        per_frame_rms(bench.catmull_rom(keys, k, s), true)))
    return np.array(out)


def run(monkeypatch, frames, triangles, gaps, protocols):
    monkeypatch.setattr(bench, "load_scene", lambda name, verbose=False: types.SimpleNamespace(
        frames=frames, triangles=triangles))
    return bench.run_scene("analytic", gaps, protocols=protocols, bake_timer=lambda name: (1.0, 1.0),
                           log=lambda line: None)


def easing_to_a_stop(frames=17):
    """A sheet that bends and rises at full pace from frame 0 and eases into a stop at the last
    frame (each quantity a parabola in time with zero velocity at the end)."""
    t = np.arange(frames) / (frames - 1)
    eased = 1.0 - (1.0 - t) ** 2
    return grid_bend(1.2 * eased + 1e-9, 0.1 * eased)


def test_sequence_rows_give_the_median_of_the_per_frame_ratios(monkeypatch):
    frames, triangles = steady_bend()
    [entry] = run(monkeypatch, frames, triangles, [4], ("seq",))
    expected = expected_rows(frames, triangles, 4)
    ours, blend, cubic = expected.T
    assert entry["ours"]["n"] == len(ours) == 12
    assert entry["ours"]["rms"] == pytest.approx(np.median(ours), rel=1e-9)
    assert entry["frames"]["linear"]["median"] == pytest.approx(np.median(ours / blend), rel=1e-9)
    assert entry["frames"]["cubic"]["median"] == pytest.approx(np.median(ours / cubic), rel=1e-9)
    assert entry["frames"]["cubic"]["above"] == int((ours > cubic).sum())
    line = bench.format_row(entry)
    assert f"| {entry['frames']['linear']['median']:.3f} / {entry['frames']['cubic']['median']:.3f} |" in line


def operators_ends(frames, first, last, step):
    """``start`` / ``end`` as *In-between Frames* computes them for frame range first … last, step
    ``step``, reading only the frames it reads (the keys and the middles of the first and last
    gaps) from ``frames`` (operators/frames.py: ``short_gap_keys``, ``start_samples``,
    ``end_samples``, ``motion_ends``)."""
    keys = list(range(first, last + 1, step))
    tail = (keys[0] + retime.short_gap_keys(keys[-1] - keys[0], last - keys[0])).tolist()
    keyed = keys + ([last] if tail else [])
    middles = [ends[3] for ends in (retime.start_samples(keyed), retime.end_samples(keyed, tail))
               if ends and ends[3] is not None]
    read = {frame: frames[frame] for frame in keyed + tail + middles}
    return retime.motion_ends(read, keyed, tail)


@pytest.mark.parametrize("g", [4, 8])
def test_the_op_protocol_builds_the_sequence_with_the_operators_ends(monkeypatch, g):
    frames, triangles = easing_to_a_stop()
    ends = operators_ends(frames, 0, len(frames) - 1, g)
    defaults = bench.sequence_ends({})
    # leaving at full pace from the keys, easing into a stop at the last one: neither end the
    # constructor's default, so the two protocols differ at both ends
    assert ends == {"start": "keys", "end": "rest"} and defaults == {"start": "rest", "end": "keys"}
    assert {k: v for k, v in bench.operator_options(frames, range(0, len(frames), g)).items()
            if k != "key_times"} == ends
    seq, op = run(monkeypatch, frames, triangles, [g], ("seq", "op"))
    assert (seq["protocol"], op["protocol"]) == ("seq", "op")
    assert seq["ends"] == defaults and op["ends"] == ends
    assert bench.format_row(op).startswith(f"| analytic | 64 | {g} | op (keys, rest) |")
    for entry, options in ((seq, {}), (op, {**ends, "key_times": list(range(0, len(frames), g))})):
        ours, blend, cubic = expected_rows(frames, triangles, g, **options).T
        assert entry["ours"]["rms"] == pytest.approx(np.median(ours), rel=1e-9)
        assert entry["frames"]["cubic"]["median"] == pytest.approx(np.median(ours / cubic), rel=1e-9)
    assert op["ours"]["rms"] != seq["ours"]["rms"]


def test_the_op_protocol_is_timed_in_every_repeat_as_seq(monkeypatch):
    frames, triangles = easing_to_a_stop()
    calls = []
    timed = bench._time_sequence

    def record(keys, triangles, factors, **options):
        calls.append(options.get("start", "default"))
        return timed(keys, triangles, factors, **options)

    monkeypatch.setattr(bench, "_time_sequence", record)
    monkeypatch.setattr(bench, "load_scene", lambda name, verbose=False: types.SimpleNamespace(
        frames=frames, triangles=triangles))
    results = bench.run_scene("analytic", [8], protocols=("seq", "op"), repeats=2,
                              bake_timer=lambda name: (1.0, 1.0), log=lambda line: None)
    assert calls == ["default", "keys"] * 2
    assert [len(r["timing"]["ours_wall"]) for r in results] == [2, 2]


def test_protocols_are_checked():
    assert bench.parse_args(["--protocols", "seq", "op", "pair"]).protocols == ["seq", "op", "pair"]
    with pytest.raises(SystemExit):
        bench.parse_args(["--protocols", "operator"])
