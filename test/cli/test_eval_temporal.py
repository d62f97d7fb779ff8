"""``eval --scene DIR --temporal``: each method's consecutive frame pairs (issue 24, item 1).

Every number is checked against a plain-numpy recomputation written here from the definition
(docs/method.md, "Temporal measures"), on the files as written: the GT read by a PFM reader
of its own, ``e = |(E_t − E_t+1) − (D_t − D_t+1)|`` at the same pixel over the pixels with
GT in both frames, each estimate under the missing-estimate policy as
:func:`reference.scored_estimate` scores it. DynamicStereo's normalisation is written from
their code (``eval_endpoint_error_sequence``: sums over a clip divided by the count of non-zero
errors; clips averaged weighted by their frames).
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from reference import POLICIES, scored_estimate

from dispeval_ros.cli.main import main
from dispeval_ros.cli.output import WIDTH

pytestmark = pytest.mark.data

SCENE = "sceneflow-flyingthings3d-seq"
FRAMES = ("0006", "0007", "0008")
ALL = ("--criteria", "all", "--measures", "mae")
DISPEVAL = {"tepe": None, "tepe_r": None, "tepe_bmp": 1.0, "tepe_bad_0.5": 0.5,
            "tepe_bad_2": 2.0, "tepe_bad_4": 4.0}  # fmt: skip
"""The default preset's measures: None for a mean, else the bad threshold in px."""
DYNAMICSTEREO = {"tepe": None, "tepe_bad_0.5": 0.5, "tepe_bad_1": 1.0, "tepe_bad_2": 2.0,
                 "tepe_bad_3": 3.0}  # fmt: skip


def read_pfm(path: Path) -> np.ndarray:
    """A one-channel PFM: ``Pf``, size, scale (< 0: little endian), rows bottom to top."""
    with path.open("rb") as handle:
        assert handle.readline().strip() == b"Pf"
        width, height = map(int, handle.readline().split())
        scale = float(handle.readline())
        data = np.frombuffer(handle.read(), dtype="<f4" if scale < 0 else ">f4")
    return np.flipud(data.reshape(height, width)).astype(np.float32)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["eval", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def temporal_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    return json.loads(out)["temporal"]


# ------------------------------------------------------------------ the independent reference


def pair_error(gt, gt_next, est, est_next, policy):
    """(e, |ΔD|) of the scored pixels of one pair, in float64 from the float32 maps."""
    value, takes_part = scored_estimate(est, policy)
    value_next, takes_part_next = scored_estimate(est_next, policy)
    both = np.isfinite(gt) & (gt > 0) & np.isfinite(gt_next) & (gt_next > 0)
    scored = both & takes_part & takes_part_next
    change = gt.astype(np.float64)[scored] - gt_next.astype(np.float64)[scored]
    return np.abs((value[scored] - value_next[scored]) - change), np.abs(change)


def dispeval_values(pairs) -> dict[str, float]:
    """The default preset: every scored pixel pair of every pair, zero errors included."""
    error = np.concatenate([e for e, _ in pairs])
    change = np.concatenate([c for _, c in pairs])
    out = {"tepe": error.mean(), "tepe_r": (error / (change + 1e-3)).mean()}
    for name, threshold in DISPEVAL.items():
        if threshold is not None:
            out[name] = 100.0 * np.count_nonzero(error > threshold) / error.size
    return out


def dynamicstereo_values(clips) -> dict[str, float]:
    """Per clip: Σ e and #{e > X} over its pairs divided by #{e ≠ 0} (at least 1e-5); then the
    clips' values averaged weighted by their frames (pairs + 1)."""
    values, weights = [], []
    for pairs in clips:
        error = np.concatenate([e for e, _ in pairs])
        nonzero = max(np.count_nonzero(error), 1e-5)
        clip = {"tepe": error.sum() / nonzero}
        for name, threshold in DYNAMICSTEREO.items():
            if threshold is not None:
                clip[name] = 100.0 * np.count_nonzero(error > threshold) / nonzero
        values.append(clip)
        weights.append(len(pairs) + 1)
    return {
        name: sum(w * v[name] for w, v in zip(weights, values, strict=True)) / sum(weights)
        for name in DYNAMICSTEREO
    }


def assert_values(got: dict, want: dict) -> None:
    for name, value in want.items():
        assert got[name] == pytest.approx(value, rel=1e-9, abs=1e-12), name


# ------------------------------------------------------------------ scenes and estimates


def noisy_estimates(folder: Path, gts: dict[str, np.ndarray], seed: int, holes: bool) -> Path:
    """Per frame: GT + N(0, 0.5²) noise drawn anew, |·| + 0.01 (valid); rows 0–39 exact (e = 0
    there); with ``holes`` a block of NaN that moves (the missing policies differ on it)."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    for index, (frame, gt) in enumerate(gts.items()):
        est = np.abs(gt + rng.normal(0.0, 0.5, gt.shape)) + 0.01
        est[:40] = gt[:40]
        if holes:
            top = 100 + 60 * index
            est[top : top + 50, 200 + 90 * index : 400 + 90 * index] = np.nan
        np.save(folder / f"{frame}.npy", est.astype(np.float32))
    return folder


@pytest.fixture(scope="module")
def scene(shared_data: Path) -> Path:
    folder = shared_data / SCENE
    if not folder.is_dir():
        pytest.skip(f"no SceneFlow frames at {folder}")
    return folder


@pytest.fixture(scope="module")
def noisy(scene: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    gts = {f: read_pfm(scene / "Disparity" / f"{f}.pfm") for f in FRAMES}
    return noisy_estimates(tmp_path_factory.mktemp("est") / "noisy", gts, 24, True), gts


SEQUENCE = ("0006", "0007", "0008", "0009", "0010", "0012", "0013")
"""The longer scene: SceneFlow's three GT maps in turn, on the 1/256 px grid (so that GT + 1 is
exact in float32), numbered with a gap at 0011."""


@pytest.fixture(scope="module")
def sequence(scene: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    from dispeval_ros.io.files import write_pfm

    folder = tmp_path_factory.mktemp("sequence") / "flying"
    (folder / "Disparity").mkdir(parents=True)
    shutil.copy(scene / "Disparity" / "Q.dat", folder / "Disparity" / "Q.dat")
    gts = {}
    for index, frame in enumerate(SEQUENCE):
        gt = read_pfm(scene / "Disparity" / f"{FRAMES[index % 3]}.pfm")
        gts[frame] = (np.round(gt.astype(np.float64) * 256) / 256).astype(np.float32)
        write_pfm(folder / "Disparity" / f"{frame}.pfm", gts[frame])
        assert np.array_equal(read_pfm(folder / "Disparity" / f"{frame}.pfm"), gts[frame])
    return folder, gts


# ------------------------------------------------------------------ the numbers


@pytest.mark.parametrize("policy", POLICIES)
def test_tepe_equals_a_numpy_recomputation_on_sceneflow(
    capsys: pytest.CaptureFixture[str], scene: Path, noisy: tuple[Path, dict], policy: str
) -> None:
    folder, gts = noisy
    argv = ("--scene", str(scene), "--est", f"noisy={folder}", *ALL, "--missing", policy)
    temporal = temporal_json(capsys, *argv, "--temporal")
    ests = {f: np.load(folder / f"{f}.npy") for f in FRAMES}
    pairs = [
        pair_error(gts[a], gts[b], ests[a], ests[b], policy) for a, b in itertools.pairwise(FRAMES)
    ]
    noisy_scores = temporal["methods"]["noisy"]
    assert (noisy_scores["pairs"], noisy_scores["runs"]) == (2, [list(FRAMES)])
    assert temporal["gaps"] == []
    got = noisy_scores["criteria"]["all"]
    want = dispeval_values(pairs)
    assert_values(got, want)
    assert got["n_pair"] == 2 * gts["0006"].size  # dense GT in both frames
    sums = noisy_scores["sums"]["all"]
    assert sums["n_pair_eval"] == sum(e.size for e, _ in pairs)
    assert sums["sum_te"] == pytest.approx(sum(e.sum() for e, _ in pairs), rel=1e-12)
    assert temporal["units"] == {"tepe": "px", "tepe_r": "e/|ΔD|", "tepe_bmp": "%",
                                 "tepe_bad_0.5": "%", "tepe_bad_2": "%", "tepe_bad_4": "%"}  # fmt: skip
    assert (temporal["preset"], temporal["missing"]) == ("dispeval", policy)
    code, out, _ = run(capsys, *argv, "--temporal")
    assert code == 0
    table = out[out.index("temporal consistency") :].splitlines()
    row = next(line.split() for line in table if line.startswith("all ") and "noisy" in line)
    assert row[2:5] == [str(got["n_pair"]), f"{want['tepe']:.4f}", f"{want['tepe_r']:.4f}"]
    assert max(len(line) for line in table) <= WIDTH


def test_the_dynamicstereo_preset_equals_their_normalisation(
    capsys: pytest.CaptureFixture[str], sequence: tuple[Path, dict], tmp_path: Path
) -> None:
    """Two clips (0006–0010, 0012–0013: the numbers jump at 0011), weighted by 5 and 2 frames;
    rows exact in every frame make #{e ≠ 0} smaller than the scored pairs, so the presets
    differ."""
    folder, gts = sequence
    ests_folder = noisy_estimates(tmp_path / "noisy", gts, 7, holes=False)
    argv = ("--scene", str(folder), "--est", f"noisy={ests_folder}", *ALL)
    theirs = temporal_json(capsys, *argv, "--temporal", "dynamicstereo")
    ours = temporal_json(capsys, *argv, "--temporal")
    ests = {f: np.load(ests_folder / f"{f}.npy") for f in SEQUENCE}
    clips = [SEQUENCE[:5], SEQUENCE[5:]]
    errors = [
        [
            pair_error(gts[a], gts[b], ests[a], ests[b], "interpolate")
            for a, b in itertools.pairwise(c)
        ]
        for c in clips
    ]
    method = theirs["methods"]["noisy"]
    assert method["runs"] == [list(c) for c in clips]
    assert method["pairs"] == 5
    assert theirs["measures"] == list(DYNAMICSTEREO)
    assert_values(method["criteria"]["all"], dynamicstereo_values(errors))
    assert_values(ours["methods"]["noisy"]["criteria"]["all"],
                  dispeval_values([p for clip in errors for p in clip]))  # fmt: skip
    assert method["criteria"]["all"]["tepe"] > ours["methods"]["noisy"]["criteria"]["all"]["tepe"]
    [gap] = theirs["gaps"]
    assert (gap["after"], gap["before"], gap["missing"], gap["unscored"]) == ("0010", "0012", [], 1)


def test_a_constant_bias_scores_zero_and_noise_does_not(
    capsys: pytest.CaptureFixture[str], sequence: tuple[Path, dict], tmp_path: Path
) -> None:
    folder, gts = sequence
    biased = tmp_path / "biased"
    biased.mkdir()
    for frame, gt in gts.items():
        est = gt + np.float32(1)
        assert np.all(est.astype(np.float64) - gt == 1.0)
        np.save(biased / f"{frame}.npy", est)
    noisy = noisy_estimates(tmp_path / "noisy", gts, 3, holes=False)
    argv = ("--scene", str(folder), "--est", f"biased={biased}", "--est", f"noisy={noisy}")
    for preset in ("dispeval", "dynamicstereo"):
        code, out, err = run(capsys, *argv, "--temporal", preset, "--json")
        assert code == 0, err
        document = json.loads(out)
        temporal = document["temporal"]
        for criterion, values in temporal["methods"]["biased"]["criteria"].items():
            for name in temporal["measures"]:
                assert values[name] == 0.0, (preset, criterion, name)
        assert temporal["methods"]["noisy"]["criteria"]["all"]["tepe"] > 0.3
        mae = {e["method"]: e["criteria"]["all"]["mae"] for e in document["frames"]}
        assert mae["biased"] == 1.0  # wrong by 1 px in every frame: accurate it is not


def test_a_missing_middle_estimate_splits_the_runs_and_is_reported(
    capsys: pytest.CaptureFixture[str], sequence: tuple[Path, dict], tmp_path: Path
) -> None:
    """``holed`` has no estimate of 0008: runs 0006–0007, 0009–0010 and 0012–0013; its
    scores pool exactly those three pairs."""
    folder, gts = sequence
    full = noisy_estimates(tmp_path / "full", gts, 5, holes=False)
    files = [f"holed={full / f}.npy" for f in SEQUENCE if f != "0008"]
    argv = ["--scene", str(folder), "--est", f"full={full}", *ALL]
    for spec in files:
        argv += ["--est", spec]
    temporal = temporal_json(capsys, *argv, "--temporal")
    holed = temporal["methods"]["holed"]
    assert holed["runs"] == [["0006", "0007"], ["0009", "0010"], ["0012", "0013"]]
    assert holed["pairs"] == 3
    assert temporal["methods"]["full"]["pairs"] == 5
    ests = {f: np.load(full / f"{f}.npy") for f in SEQUENCE}
    pairs = [("0006", "0007"), ("0009", "0010"), ("0012", "0013")]
    errors = [pair_error(gts[a], gts[b], ests[a], ests[b], "interpolate") for a, b in pairs]
    assert_values(holed["criteria"]["all"], dispeval_values(errors))
    gaps = [(g["method"], g["after"], g["before"], g["missing"], g["unscored"])
            for g in temporal["gaps"]]  # fmt: skip
    assert gaps == [
        ("full", "0010", "0012", [], 1),
        ("holed", "0007", "0009", ["0008"], 0),
        ("holed", "0010", "0012", [], 1),
    ]
    code, out, _ = run(capsys, *argv, "--temporal")
    assert code == 0
    assert "gap: holed: no pair 0007 → 0009: no estimate of frame 0008" in out
    assert "gap: full: no pair 0010 → 0012: 1 frame number between not scored" in out
    assert "holed: 3 runs (0006–0007; 0009–0010; 0012–0013), 3 pairs" in out


# ------------------------------------------------------------------ bad input, options, storing


def test_a_change_of_ground_truth_source_ends_a_run(
    capsys: pytest.CaptureFixture[str], shared_data: Path, tmp_path: Path
) -> None:
    """KITTI LiDAR frames 000010–000012 (000010's scan and images thrice): 000010 has its
    official map, the others only the scan, so ``auto`` scores 000010 against the map and the
    others against the scan; no pair crosses the change."""
    source = shared_data / "kitti-lidar"
    folder = tmp_path / "drive"
    for sub in ("velodyne_points", "image_02", "image_03", "gt/disp_occ_0"):
        (folder / sub).mkdir(parents=True)
    (tmp_path / "calib").symlink_to(source / "raw-calib-2011_09_26")
    kitti = source / "kitti2015-with-velodyne"
    for frame in ("000010", "000011", "000012"):
        shutil.copy(
            kitti / "velodyne_points" / "000010.bin", folder / "velodyne_points" / f"{frame}.bin"
        )
        for side in ("image_02", "image_03"):
            shutil.copy(kitti / side / "000010.png", folder / side / f"{frame}.png")
    shutil.copy(kitti / "gt" / "disp_occ_0" / "000010.png", folder / "gt" / "disp_occ_0")
    estimate = kitti / "prediction" / "000010.png"
    estimates = tmp_path / "psmnet"
    estimates.mkdir()
    for frame in ("000010", "000011", "000012"):
        shutil.copy(estimate, estimates / f"{frame}.png")
    argv = ["--scene", str(folder), "--est", f"psmnet={estimates}", *ALL, "--temporal"]
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    document = json.loads(out)
    assert [f["gt_source"] for f in document["frames"]] == ["official", "scan", "scan"]
    temporal = document["temporal"]
    assert temporal["methods"]["psmnet"]["runs"] == [["000010"], ["000011", "000012"]]
    assert temporal["methods"]["psmnet"]["pairs"] == 1
    [gap] = temporal["gaps"]
    assert gap["gt_sources"] == ["official", "scan"]
    # the same scan and estimate twice: nothing changes from 000011 to 000012
    scores = temporal["methods"]["psmnet"]["criteria"]["all"]
    assert scores["n_pair"] > 10000
    assert scores["tepe"] == 0.0
    code, out, _ = run(capsys, *argv)
    assert code == 0
    assert (
        "gap: psmnet: no pair 000010 → 000011: the ground truth changes from official GT map to "
        "projected LiDAR scan" in " ".join(out.split())
    )


@pytest.mark.parametrize(
    ("where", "extra", "words"),
    [
        ("tartanair-oldtown", (), "one frame of"),
        (SCENE, ("--frame", "0007"), "(--frame chose it)"),
    ],
)
def test_a_one_frame_scene_is_one_line_exit_2(
    capsys: pytest.CaptureFixture[str], shared_data: Path, where: str, extra: tuple, words: str
) -> None:
    folder = shared_data / where
    estimate = next(folder.glob("*_left_disp.npy"), folder / "Disparity" / "0007.pfm")
    code, out, err = run(
        capsys, "--scene", str(folder), "--est", f"m={estimate}", *extra, *ALL, "--temporal"
    )
    assert (code, out) == (2, "")
    assert len(err.strip().splitlines()) == 1
    assert "--temporal scores pairs of consecutive frames" in err
    assert words in err


@pytest.mark.parametrize(
    ("names", "words"),
    [
        (("000010", "pose"), "frame pose of"),
        (("000010", "000012"), "no method has estimates of two consecutive frames"),
    ],
)
def test_unnumbered_or_unpaired_frames_are_one_line_exit_2(
    capsys: pytest.CaptureFixture[str], shared_data: Path, tmp_path: Path, names, words: str
) -> None:
    """A TartanAir folder of two frames (its one frame twice) with an estimate of each."""
    source = shared_data / "tartanair-oldtown"
    shutil.copy(source / "Q.dat", tmp_path / "Q.dat")
    estimates = tmp_path / "est"
    estimates.mkdir()
    for name in names:
        shutil.copy(source / "001116_left_disp.npy", tmp_path / f"{name}_left_disp.npy")
        shutil.copy(source / "001116_left_disp.npy", estimates / f"{name}.npy")
    argv = ("--scene", str(tmp_path), "--est", f"m={estimates}", *ALL)
    assert run(capsys, *argv)[0] == 0
    code, out, err = run(capsys, *argv, "--temporal")
    assert (code, out) == (2, "")
    assert len(err.strip().splitlines()) == 1
    assert words in err


def test_temporal_without_a_scene_or_with_a_protocol_is_refused(
    capsys: pytest.CaptureFixture[str], scene: Path
) -> None:
    gt = scene / "Disparity" / "0006.pfm"
    code, _, err = run(capsys, "--gt", str(gt), "--est", f"m={gt}", "--temporal")
    assert code == 2
    assert "--temporal scores the consecutive frames of a scene folder: give --scene DIR" in err
    code, _, err = run(
        capsys, "--scene", str(scene), "--est", f"m={gt}", "--protocol", "kitti2015", "--temporal"
    )
    assert code == 2
    assert "--temporal does not apply with --protocol" in err


def test_without_temporal_nothing_changes(
    capsys: pytest.CaptureFixture[str], scene: Path, noisy: tuple[Path, dict]
) -> None:
    argv = ("--scene", str(scene), "--est", f"noisy={noisy[0]}", *ALL)
    plain_code, plain, _ = run(capsys, *argv)
    code, with_temporal, _ = run(capsys, *argv, "--temporal")
    assert plain_code == code == 0
    assert "temporal" not in plain
    assert with_temporal.startswith(plain.rstrip("\n") + "\n\ntemporal consistency over frames")
    documents = []
    for extra in ((), ("--temporal",)):
        code, out, _ = run(capsys, *argv, *extra, "--json")
        document = json.loads(out)
        documents.append(document)
    assert "temporal" not in documents[0]
    assert "temporal" not in documents[0]["provenance"]["configuration"]
    assert documents[1]["provenance"]["configuration"]["temporal"] == "dispeval"
    del documents[1]["temporal"]
    for document in documents:
        del document["provenance"]
    assert documents[0] == documents[1]


def test_out_stores_the_temporal_scores_with_the_sequence(
    capsys: pytest.CaptureFixture[str], scene: Path, noisy: tuple[Path, dict], tmp_path: Path
) -> None:
    from dispeval_ros.io.store import ResultsStore

    argv = ("--scene", str(scene), "--est", f"noisy={noisy[0]}", *ALL, "--temporal")
    temporal = temporal_json(capsys, *argv)
    code, _, err = run(capsys, *argv, "--out", str(tmp_path / "out"))
    assert code == 0, err
    with ResultsStore.open(tmp_path / "out") as store:
        [name] = store.sequences()
        _, info = store.sequence_info(name)
        assert info["temporal"] == temporal
        assert store.config()["temporal"] == "dispeval"


# ------------------------------------------------------------------ the README's example

CLONE = Path(__file__).resolve().parents[2]


def readme_example() -> tuple[str, list[str], str]:
    """The example block's Python code, its ``eval`` arguments, and the README text after it."""
    text = (CLONE / "README.md").read_text(encoding="utf-8")
    match = re.search(
        r"<!-- temporal-example -->\n```bash\n(.*?)```\n<!-- /temporal-example -->\n", text, re.S
    )
    assert match, "README.md has no temporal-example block"
    block = match.group(1)
    code = re.search(r'python -c "(.*?)"\n', block, re.S)
    assert code
    command = shlex.split(block[block.index("dispeval eval") :].replace("\\\n", " "))
    after = text[match.end() :]
    return code.group(1), command[2:], after[: after.index("\n## ")]


def test_the_readme_example_prints_the_readme_numbers(
    capsys: pytest.CaptureFixture[str], scene: Path, tmp_path: Path, monkeypatch
) -> None:
    code, argv, text = readme_example()
    (tmp_path / SCENE).symlink_to(scene)
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(CLONE), *sys.path])}
    subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, env=environment)
    monkeypatch.chdir(tmp_path)
    ours = json.loads(run(capsys, *argv, "--json")[1])
    theirs = temporal_json(capsys, *argv, "dynamicstereo")
    rows = {line.split("|")[1].strip(): line.split("|")[2:-1] for line in text.splitlines()
            if line.startswith(("| sgbm ", "| bm_fast "))}  # fmt: skip
    assert list(rows) == ["sgbm", "bm_fast"]
    for method, cells in rows.items():
        values = ours["temporal"]["methods"][method]["criteria"]["all"]
        shown = [values["tepe"], values["tepe_r"], values["tepe_bmp"]]
        assert [c.strip() for c in cells[:3]] == [f"{v:.2f}" for v in shown]
        bad = [values[f"tepe_bad_{t}"] for t in ("0.5", "2", "4")]
        assert cells[3].strip() == " / ".join(f"{v:.2f}" for v in bad)
        mae = [e["criteria"]["all"]["mae"] for e in ours["frames"] if e["method"] == method]
        assert cells[4].strip() == ", ".join(f"{v:.2f}" for v in mae)
        assert values["n_pair"] == 1036800
    methods = ours["temporal"]["methods"]
    text = " ".join(text.split())  # the sentences, whatever their line breaks
    zeros = [int(m["sums"]["all"]["n_pair_eval"] - m["sums"]["all"]["n_pair_nonzero"])
             for m in methods.values()]  # fmt: skip
    assert f"only {zeros[0]} and {zeros[1]} of the 1036800 pixel pairs" in text
    tepe = " / ".join(f"{m['criteria']['all']['tepe']:.2f}" for m in theirs["methods"].values())
    bad3 = " / ".join(
        f"{m['criteria']['all']['tepe_bad_3']:.2f}" for m in theirs["methods"].values()
    )
    assert f"`tepe` {tepe} px too" in text
    assert f"`tepe_bad_3` {bad3} %" in text
    sgbm = methods["sgbm"]["criteria"]
    assert f"(sgbm {sgbm['interior']['tepe']:.2f} px)" in text
    assert f"most ({sgbm['occluded']['tepe']:.2f} px)" in text
