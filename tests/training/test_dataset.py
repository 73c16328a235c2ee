"""Bags → runs → split → z-score → windows, on small real bags written to tmp."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.features import CHANNELS, feature_set
from sideslip_msgs_py.sample import SampleArrays
from sideslip_training.dataset import (
    DatasetError,
    Run,
    data_digest,
    find_bags,
    load_runs,
)
from sideslip_training.normalize import Normalizer
from sideslip_training.splits import split_runs
from sideslip_training.windows import WindowIndex

T = 100
SIM_BAG_NAMES = ("dlc_70", "sine_60", "sine_80", "straight_50")  # conftest's sim_bag_dir
MakeArrays = Callable[..., SampleArrays]
WriteArrays = Callable[..., Path]


def _run(name: str, arrays: SampleArrays, bag: str = "") -> Run:
    return Run(name=name, path=Path(name), samples=arrays, bag=bag)


def _windows_of(index: WindowIndex) -> tuple[np.ndarray, np.ndarray]:
    return index.batch(np.arange(len(index)))


# --- finding and loading ----------------------------------------------------------------------


def test_find_bags_accepts_folders_bag_dirs_and_bare_mcap_without_duplicates(
    sim_bag_dir: Path,
) -> None:
    assert (sim_bag_dir / "index.json").is_file()
    bags = find_bags([sim_bag_dir])
    assert [b.name for b in bags] == sorted(SIM_BAG_NAMES)
    bare = sim_bag_dir / "sine_60" / "sine_60.mcap"
    again = find_bags([sim_bag_dir / "sine_80", sim_bag_dir, str(sim_bag_dir / "sine_80"), bare])
    assert again == sorted([*bags, bare.resolve()])


def test_missing_path_and_empty_folder_are_errors_naming_the_path(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere"
    with pytest.raises(DatasetError, match=str(missing)):
        find_bags([missing])
    with pytest.raises(DatasetError, match=str(missing)):
        load_runs([missing])
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "index.json").write_text("{}")
    with pytest.raises(DatasetError, match=rf"{empty}: holds no bag"):
        find_bags([empty])


def test_simulated_folder_loads_every_bag_with_its_metadata(sim_bag_dir: Path) -> None:
    runs, report = load_runs([sim_bag_dir])
    assert [r.name for r in runs] == sorted(SIM_BAG_NAMES)
    assert all(len(r) == 400 and r.samples.has_truth and not r.truncated for r in runs)
    assert runs[0].run_metadata["preset"] == "test"
    assert (report.bags_found, report.bags_used, report.runs, report.samples) == (4, 4, 4, 1600)
    assert report.refused == () and report.gaps == 0 and report.nonfinite_samples == 0
    assert str(report).startswith("4 of 4 bag(s) used: 4 run(s), 1600 samples")


def test_bare_mcap_reads_the_same_samples_as_its_bag_directory(sim_bag_dir: Path) -> None:
    (from_dir,), _ = load_runs([sim_bag_dir / "sine_60"])
    (from_mcap,), _ = load_runs([sim_bag_dir / "sine_60" / "sine_60.mcap"])
    assert from_mcap.name == from_dir.name == "sine_60"
    assert from_mcap.samples == from_dir.samples
    assert from_mcap.run_metadata == from_dir.run_metadata


def test_bag_without_ground_truth_is_refused_by_name(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    write_arrays("with_truth", make_arrays(300))
    write_arrays("no_truth", make_arrays(300, truth=False))
    runs, report = load_runs([tmp_path])
    assert [r.name for r in runs] == ["with_truth"]
    assert report.refused == ("no_truth: no ground truth",)
    assert "no_truth: no ground truth" in str(report)

    runs, report = load_runs([tmp_path], require_truth=False)
    assert [r.name for r in runs] == ["no_truth", "with_truth"]
    with pytest.raises(DatasetError, match=r"no usable run.*no_truth: no ground truth"):
        load_runs([tmp_path / "no_truth"])


def test_unreadable_bag_is_reported_and_the_rest_used(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    write_arrays("good", make_arrays(300))
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all")
    (tmp_path / "magic_only.mcap").write_bytes(b"\x89MCAP0\r\n")
    runs, report = load_runs([tmp_path])
    assert [r.name for r in runs] == ["good"]
    assert [r.split(":")[0] for r in report.refused] == ["junk", "magic_only"]
    assert all(": unreadable (" in r for r in report.refused)
    assert any(line.startswith("junk: ERROR unreadable") for line in report.lines)
    with pytest.raises(DatasetError, match="junk: unreadable"):
        load_runs([tmp_path / "junk.mcap"])


def test_truncated_bag_uses_its_readable_part_and_is_reported(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    arrays = make_arrays(4000)  # several 1-MiB chunks
    bag = write_arrays("long", arrays, folder=tmp_path / "src")
    data = (bag / "long.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])

    (run,), report = load_runs([cut])
    assert run.truncated and report.truncated == ("cut",)
    n = len(run)
    assert 0 < n < len(arrays)
    assert np.array_equal(run.samples.x_v_mps, arrays.x_v_mps[:n])
    assert any(line.startswith("cut: truncated bag") for line in report.lines)
    assert any("unreadable after" in note for note in run.notes)


def test_gap_in_time_splits_the_bag_into_named_segments(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    stamps = np.arange(700, dtype=np.int64) * 2_500_000
    stamps[300:] += 500_000_000  # 0.5 s without samples after sample 299
    write_arrays("gappy", make_arrays(700, stamps_ns=stamps))
    runs, report = load_runs([tmp_path])
    assert [(r.name, r.bag, len(r)) for r in runs] == [
        ("gappy#0", "gappy", 300),
        ("gappy#1", "gappy", 400),
    ]
    assert report.gaps == 1 and report.runs == 2 and report.bags_used == 1
    assert any("gappy: 1 gap(s)" in line and "gappy#0..gappy#1" in line for line in report.lines)
    # a tolerance wider than the gap keeps it whole
    (whole,), _ = load_runs([tmp_path], max_gap_s=1.0)
    assert whole.name == "gappy" and len(whole) == 700


def test_nonfinite_samples_are_reported_with_counts(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    arrays = make_arrays(400)
    y_v = arrays.y_v_mps.copy()
    y_v[[10, 11, 250]] = np.nan
    cols = {k: v for k, v in vars(arrays).items()} | {"y_v_mps": y_v}
    write_arrays("holes", SampleArrays(**cols))
    _, report = load_runs([tmp_path])
    assert report.nonfinite_samples == 3
    assert any("holes: 3 sample(s) with NaN/inf (y_v_mps: 3)" in line for line in report.lines)
    # only the channels asked for are checked: `measurable` does not read Y_v
    _, report = load_runs([tmp_path], channels=feature_set("measurable"))
    assert report.nonfinite_samples == 0


# --- windows ----------------------------------------------------------------------------------


@pytest.mark.parametrize("features", [feature_set("paper"), feature_set("measurable")])
def test_window_ends_on_the_sample_whose_beta_is_its_target(
    sim_bag_dir: Path, features: tuple[str, ...]
) -> None:
    runs, _ = load_runs([sim_bag_dir])
    order = tuple(reversed(features))  # any order the caller asks for is kept
    norm = Normalizer.fit(runs, order)
    index = WindowIndex.build(runs, order, norm, window_steps=T, stride=1)
    assert index.x.shape == (1600, len(order)) and index.x.dtype == np.float32
    assert len(index) == 4 * (400 - T + 1)
    picks = np.array([0, 1, 300, 301, len(index) - 1])
    X, Y = index.batch(picks)
    assert X.shape == (5, T, len(order)) and Y.shape == (5,)
    for i, w in enumerate(picks):
        run = runs[index.run_of_window[w]]
        local_end = int(index.ends[w] - index.run_starts[index.run_of_window[w]])
        raw = np.column_stack([getattr(run.samples, c) for c in order])
        expect = norm.apply_features(raw[local_end - T + 1 : local_end + 1]).astype(np.float32)
        np.testing.assert_array_equal(X[i], expect)
        assert Y[i] == np.float32(norm.apply_beta(run.samples.beta_rad()[local_end]))
        # the last row, un-normalised, is the raw sample at the target's stamp
        back = X[i, -1].astype(np.float64) * norm.std + norm.mean
        assert np.all(np.abs(back - raw[local_end]) <= 1e-6 * norm.std)
        assert index.stamp_ns[index.ends[w]] == run.samples.stamp_ns[local_end]
    if "y_v_mps" not in features:
        assert index.features == order and "y_v_mps" not in index.features


def test_windows_never_cross_runs_gaps_or_nonfinite_samples(
    make_arrays: MakeArrays, write_arrays: WriteArrays, tmp_path: Path
) -> None:
    stamps = np.arange(900, dtype=np.int64) * 2_500_000
    stamps[450:] += 100_000_000
    arrays = make_arrays(900, stamps_ns=stamps)
    stl = arrays.stl_m.copy()
    stl[[150, 700]] = np.nan
    truth_v_y = arrays.truth_v_y_mps.copy()
    truth_v_y[600] = np.nan  # β NaN: no window may end there, but it may lie inside one
    cols = vars(arrays) | {"stl_m": stl, "truth_v_y_mps": truth_v_y}
    write_arrays("a", SampleArrays(**cols))
    write_arrays("b", make_arrays(250, seed=1))
    runs, _ = load_runs([tmp_path])
    assert [r.name for r in runs] == ["a#0", "a#1", "b"]
    norm = Normalizer.fit(runs, CHANNELS)
    index = WindowIndex.build(runs, CHANNELS, norm, window_steps=T, stride=1)

    starts = index.ends - T + 1
    run_start = index.run_starts[index.run_of_window]
    run_stop = index.run_starts[index.run_of_window + 1]
    assert np.all(starts >= run_start) and np.all(index.ends < run_stop)
    X, Y = _windows_of(index)
    assert np.isfinite(X).all() and np.isfinite(Y).all()
    rows = starts[:, None] + np.arange(T)
    assert np.diff(index.stamp_ns[rows], axis=1).max() <= 10_000_000
    # exactly the windows that avoid samples 150 (a#0), 700 (a#1 local 250) and end ≠ 600
    expected = (
        len([e for e in range(T - 1, 450) if not e - T + 1 <= 150 <= e])
        + len([e for e in range(T - 1, 450) if not e - T + 1 <= 250 <= e and e != 150])
        + (250 - T + 1)
    )
    assert len(index) == expected
    assert any(note.startswith("a#0:") and "left out" in note for note in index.notes)


def test_short_run_gives_no_window_and_a_note(make_arrays: MakeArrays) -> None:
    runs = [_run("short", make_arrays(T - 1)), _run("exact", make_arrays(T, seed=2))]
    norm = Normalizer.fit(runs, CHANNELS)
    index = WindowIndex.build(runs, CHANNELS, norm, window_steps=T)
    assert index.ends.tolist() == [T - 1 + T - 1]
    assert index.run_of_window.tolist() == [1]
    assert index.notes == (f"short: {T - 1} samples, shorter than one window ({T})",)


@pytest.mark.parametrize("stride", [1, 7, 10, 301])
def test_windows_start_every_stride_samples_from_the_start_of_each_run(
    make_arrays: MakeArrays, stride: int
) -> None:
    runs = [_run("a", make_arrays(400)), _run("b", make_arrays(333, seed=1))]
    norm = Normalizer.fit(runs, CHANNELS)
    index = WindowIndex.build(runs, CHANNELS, norm, window_steps=T, stride=stride)
    for r, n in enumerate((400, 333)):
        local = index.ends[index.run_of_window == r] - index.run_starts[r]
        assert local.tolist() == list(range(T - 1, n, stride))  # first window always in
    assert len(index) == sum((n - T) // stride + 1 for n in (400, 333))


def test_torch_gather_equals_numpy_gather(sim_bag_dir: Path) -> None:
    runs, _ = load_runs([sim_bag_dir])
    norm = Normalizer.fit(runs, CHANNELS)
    index = WindowIndex.build(runs, CHANNELS, norm, window_steps=T, stride=3)
    on_device = index.to_torch("cpu")
    assert len(on_device) == len(index)
    picks = np.random.default_rng(0).choice(len(index), size=64, replace=False)
    X, Y = on_device.batch(torch.from_numpy(picks))
    X_np, Y_np = index.batch(picks)
    assert X.dtype == torch.float32 and X.shape == (64, T, 6)
    assert np.array_equal(X.numpy(), X_np) and np.array_equal(Y.numpy(), Y_np)


def test_build_refuses_features_other_than_the_normalizers(make_arrays: MakeArrays) -> None:
    runs = [_run("a", make_arrays(200))]
    norm = Normalizer.fit(runs, feature_set("measurable"))
    with pytest.raises(DatasetError, match="differ from the normalizer"):
        WindowIndex.build(runs, feature_set("paper"), norm)


# --- split --------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(
    bags=st.lists(
        st.text(alphabet="abcxyz_#0123456789", min_size=1, max_size=8),
        min_size=2,
        max_size=30,
        unique=True,
    ),
    segments=st.lists(st.integers(1, 3), min_size=30, max_size=30),
    val_fraction=st.floats(0.01, 0.99),
    seed=st.integers(0, 2**32),
)
def test_split_keeps_every_bag_on_one_side(
    bags: list[str], segments: list[int], val_fraction: float, seed: int
) -> None:
    tiny = SampleArrays(np.zeros(1, np.int64), *([np.zeros(1)] * 7))
    runs = [
        _run(f"{bag}#{k}" if n > 1 else bag, tiny, bag=bag)
        for bag, n in zip(bags, segments, strict=False)
        for k in range(n)
    ]
    train, val = split_runs(runs, val_fraction, seed)
    assert train and val
    assert not {r.bag for r in train} & {r.bag for r in val}
    assert len(train) + len(val) == len(runs)
    # deterministic, and independent of the order the runs come in
    again_train, again_val = split_runs(list(reversed(runs)), val_fraction, seed)
    assert {r.name for r in again_val} == {r.name for r in val}
    assert {r.name for r in again_train} == {r.name for r in train}


def test_split_sizes_follow_val_fraction(make_arrays: MakeArrays) -> None:
    tiny = make_arrays(2)
    runs = [_run(f"r{i}", tiny) for i in range(10)]
    train, val = split_runs(runs, 0.2, seed=0)
    assert (len(train), len(val)) == (8, 2)
    assert [r.name for r in train] == [r.name for r in runs if r not in val]  # order kept
    assert split_runs(runs, 0.0, seed=0) == (runs, [])
    assert split_runs(runs, 0.2, seed=1) != (train, val)  # another seed, another split


def test_one_bag_cannot_be_split_without_leaking(make_arrays: MakeArrays) -> None:
    runs = [_run("only#0", make_arrays(5), bag="only"), _run("only#1", make_arrays(5), "only")]
    with pytest.raises(DatasetError, match=r"1 bag \(only\).*leak"):
        split_runs(runs, 0.2, seed=0)
    assert split_runs(runs, 0.0, seed=0) == (runs, [])


# --- normalizer -----------------------------------------------------------------------------------


@given(st.lists(st.floats(-1.5, 1.5), min_size=1, max_size=50))
def test_beta_zscore_round_trips(betas: list[float]) -> None:
    norm = Normalizer(CHANNELS, np.zeros(6), np.ones(6), beta_mean=0.013, beta_std=0.041)
    b = np.array(betas)
    np.testing.assert_allclose(norm.invert_beta(norm.apply_beta(b)), b, rtol=0, atol=1e-12)


def test_normalizer_is_fitted_on_the_runs_it_is_given_only(make_arrays: MakeArrays) -> None:
    train = [_run("t0", make_arrays(500)), _run("t1", make_arrays(300, seed=1))]
    val = [_run("v0", make_arrays(400, seed=2, v_x_mps=45.0))]  # much faster: another mean
    norm = Normalizer.fit(train, CHANNELS)
    x_v = np.concatenate([r.samples.x_v_mps for r in train])
    assert norm.mean[0] == pytest.approx(x_v.mean(), rel=1e-12)
    assert norm.std[0] == pytest.approx(x_v.std(), rel=1e-12)
    beta = np.concatenate([r.samples.beta_rad() for r in train])
    assert (norm.beta_mean, norm.beta_std) == pytest.approx((beta.mean(), beta.std()), rel=1e-12)
    assert Normalizer.fit(train + val, CHANNELS).mean[0] > norm.mean[0] + 5.0
    # validation windows are normalised with the training statistics
    index = WindowIndex.build(val, CHANNELS, norm, window_steps=T)
    assert index.x[:, 0].mean() > 10.0


def test_constant_channel_gets_unit_std_and_a_note(make_arrays: MakeArrays) -> None:
    arrays = make_arrays(300)
    cols = vars(arrays) | {"stl_m": np.full(300, 0.004)}
    norm = Normalizer.fit([_run("flat", SampleArrays(**cols))], CHANNELS)
    assert norm.std[CHANNELS.index("stl_m")] == 1.0
    assert norm.mean[CHANNELS.index("stl_m")] == pytest.approx(0.004)
    assert len(norm.notes) == 1 and norm.notes[0].startswith("stl_m is constant")


def test_normalizer_dict_round_trips_through_json_exactly(sim_bag_dir: Path) -> None:
    runs, _ = load_runs([sim_bag_dir])
    norm = Normalizer.fit(runs, feature_set("measurable"))
    back = Normalizer.from_dict(json.loads(json.dumps(norm.to_dict())))
    assert back == norm
    assert np.array_equal(back.mean, norm.mean) and back.beta_std == norm.beta_std
    with pytest.raises(DatasetError, match="unknown keys \\['extra'\\]"):
        Normalizer.from_dict(norm.to_dict() | {"extra": 1})


# --- digest --------------------------------------------------------------------------------------


def test_data_digest_is_stable_and_sees_every_sample(
    sim_bag_dir: Path, make_arrays: MakeArrays, tmp_path: Path
) -> None:
    runs, _ = load_runs([sim_bag_dir])
    digest = data_digest(runs)
    assert len(digest) == 64
    again, _ = load_runs([sim_bag_dir])
    assert data_digest(list(reversed(again))) == digest

    copy = tmp_path / "copy"
    shutil.copytree(sim_bag_dir, copy)
    assert data_digest(load_runs([copy])[0]) == digest  # the path is not part of it
    changed = runs[0].samples
    x_a = changed.x_a_mps2.copy()
    x_a[123] += 1e-9
    cols = vars(changed) | {"x_a_mps2": x_a}
    edited = [Run(runs[0].name, runs[0].path, SampleArrays(**cols)), *runs[1:]]
    assert data_digest(edited) != digest


# --- the model's rate ------------------------------------------------------------------------


def test_bags_at_another_rate_are_resampled_to_the_models_step_and_reported(
    make_arrays, write_arrays, tmp_path
) -> None:
    folder = tmp_path / "bags"
    write_arrays("at100", make_arrays(400, stamps_ns=np.arange(400) * 10_000_000), folder=folder)
    write_arrays("at400", make_arrays(1600), folder=folder)
    runs, report = load_runs(folder, step_s=0.0025)
    by_name = {r.name: r for r in runs}
    slow = by_name["at100"].samples
    assert np.all(np.diff(slow.stamp_ns) == 2_500_000) and len(slow) == 399 * 4 + 1
    assert "at100: resampled from 100.0 Hz to 400 Hz (linear interpolation)" in str(report)
    assert "at400: resampled" not in str(report)
    assert len(by_name["at400"].samples) == 1600


def test_a_bag_too_slow_to_resample_is_refused_naming_both_rates(
    make_arrays, write_arrays, tmp_path
) -> None:
    folder = tmp_path / "bags"
    write_arrays("at20", make_arrays(100, stamps_ns=np.arange(100) * 50_000_000), folder=folder)
    write_arrays("at400", make_arrays(800), folder=folder)
    runs, report = load_runs(folder, step_s=0.0025)
    assert [r.name for r in runs] == ["at400"]
    assert "at20: ERROR samples at 20.0 Hz" in str(report) and "400 Hz" in str(report)
    with pytest.raises(DatasetError, match=r"20\.0 Hz"):
        load_runs(folder / "at20", step_s=0.0025)


def test_split_in_time_takes_each_bags_last_part_and_no_window_spans_the_cut(
    make_arrays, write_arrays, tmp_path
) -> None:
    from sideslip_training.splits import split_in_time

    stamps = np.concatenate([np.arange(600), 1000 + np.arange(400)]) * 2_500_000  # a gap
    write_arrays("long", make_arrays(1000, stamps_ns=stamps), folder=tmp_path / "b")
    write_arrays("other", make_arrays(500, seed=1), folder=tmp_path / "b")
    runs, _ = load_runs(tmp_path / "b")
    assert [r.name for r in runs] == ["long#0", "long#1", "other"]
    head, tail = split_in_time(runs, 0.3, "test")
    by_bag = {}
    for r in head + tail:
        by_bag.setdefault(r.bag, []).append(r)
    assert sum(len(r) for r in tail if r.bag == "long") == 300
    assert sum(len(r) for r in tail if r.bag == "other") == 150
    for bag, mine in by_bag.items():
        last_head = max(int(r.samples.stamp_ns[-1]) for r in mine if r in head)
        first_tail = min(int(r.samples.stamp_ns[0]) for r in mine if r in tail)
        assert last_head < first_tail, bag  # the tail is later in time
    assert all(r.name.endswith("@test") for r in tail)
    assert sum(len(r) for r in head + tail) == 1500  # nothing lost or doubled
    with pytest.raises(DatasetError, match="too few"):
        split_in_time([r for r in runs if r.name == "other"][:1], 0.0001, "x")
