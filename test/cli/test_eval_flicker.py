"""``eval --scene FRAMES --flicker [N]``: flicker over a scene's frames, checked against numpy.

The scene is a static camera in the SceneFlow layout (``Left/``, ``Right/``, ``Disparity/``
with ``Q.dat``): the same textured view in every frame with per-frame sensor noise of at most
±2 grey levels, and the same ground truth, a smooth plane (no depth edge), so no mask applies.
``true`` is the ground truth, ``noisy`` the ground truth plus per-frame noise: each window of
the JSON equals ``np.std(stack, axis=0, ddof=1)`` of the maps given; the true map flickers 0.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.io.files import write_pfm

FRAMES, H, W, SIGMA, F, B = 6, 40, 64, 0.4, 500.0, 0.1
PLANE = (25.0 + 0.03 * np.arange(W, dtype=np.float32))[None, :].repeat(H, 0)


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("still")
    for side in ("Left", "Right", "Disparity", "true", "noisy"):
        (root / side).mkdir()
    (root / "Disparity" / "Q.dat").write_text(
        f"1 0 0 {-W / 2}\n0 1 0 {-H / 2}\n0 0 0 {F}\n0 0 {1 / B} 0\n"
    )
    rng = np.random.default_rng(3)
    view = rng.integers(20, 235, (H, W)).astype(np.int64)
    for index in range(FRAMES):
        name = f"{index:04d}"
        for side in ("Left", "Right"):
            shaken = np.clip(view + rng.integers(-2, 3, view.shape), 0, 255).astype(np.uint8)
            cv2.imwrite(str(root / side / f"{name}.png"), shaken)
        write_pfm(root / "Disparity" / f"{name}.pfm", PLANE)
        np.save(root / "true" / f"{name}.npy", PLANE)
        noisy = PLANE + rng.normal(0, SIGMA, PLANE.shape).astype(np.float32)
        np.save(root / "noisy" / f"{name}.npy", noisy)
    return root


def run(scene: Path, *extra: str, capsys: pytest.CaptureFixture[str]) -> dict:
    line = ["eval", "--scene", str(scene), "--est", f"true={scene / 'true'}",
            "--est", f"noisy={scene / 'noisy'}", "--criteria", "all", "--json", *extra]  # fmt: skip
    assert main(line) == 0
    return json.loads(capsys.readouterr().out)


def numpy_windows(scene: Path, method: str, size: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per window of ``size`` frames (the last one shorter), the disparity and depth spreads."""
    maps = [np.load(scene / method / f"{i:04d}.npy").astype(np.float64) for i in range(FRAMES)]
    out = []
    for start in range(0, FRAMES, size):
        stack = np.stack(maps[start : start + size])
        out.append((np.std(stack, axis=0, ddof=1), np.std(F * B / stack, axis=0, ddof=1)))
    return out


@pytest.mark.parametrize(("size", "windows"), [(3, 2), (4, 2)])
def test_each_method_equals_numpy_over_its_windows(
    scene: Path, size: int, windows: int, capsys: pytest.CaptureFixture[str]
) -> None:
    entry = run(scene, "--gt-free", "--gt-free-criteria", "all", "--flicker", str(size),
                capsys=capsys)["flicker"]  # fmt: skip
    assert entry["label"] == "temporal noise of a static camera, not accuracy"
    assert (entry["window"], entry["problems"]) == (size, [])
    assert entry["frames"] == [f"{i:04d}" for i in range(FRAMES)]
    for method in ("true", "noisy"):
        mine = entry["methods"][method]
        assert (mine["windows"], mine["frames"]) == (windows, FRAMES)
        sums = dict(zip(mine["columns"], mine["sums"]["gtfree:all"], strict=True))
        spreads = numpy_windows(scene, method, size)
        assert sums["n_residual"] == windows * H * W  # no mask applies
        expected = sum(s.sum() for s, _ in spreads)
        assert sums["sum"] == pytest.approx(expected, rel=1e-6, abs=1e-9)
        assert sums["sum_sq"] == pytest.approx(
            sum((s**2).sum() for s, _ in spreads), abs=1e-9, rel=1e-6
        )
        assert sums["sum_abs_z"] == pytest.approx(
            sum(z.sum() for _, z in spreads), rel=1e-5, abs=1e-12
        )
        assert sums["bad_0.5"] == sum(np.count_nonzero(s > 0.5) for s, _ in spreads)
    assert entry["methods"]["true"]["criteria"]["gtfree:all"]["mean"] == 0.0


def test_without_images_flicker_counts_every_pixel_on_all(
    scene: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    entry = run(scene, "--flicker", capsys=capsys)["flicker"]
    noisy = entry["methods"]["noisy"]
    assert (noisy["windows"], noisy["frames"]) == (1, 5)  # 5 frames, then 1: a line
    assert list(noisy["criteria"]) == ["gtfree:all"]
    assert len(entry["problems"]) == 2  # a window of 1 frame per method
    assert all(
        "(1 frame) ended by the end of the stream: not scored" in p for p in entry["problems"]
    )


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--flicker", "1"], "--flicker: a flicker window needs at least 2 frames"),
        (["--gt", "x.pfm", "--flicker"], "--flicker scores the consecutive frames of a scene"),
    ],
)
def test_what_cannot_be_scored_is_one_line(
    tmp_path: Path, extra: list[str], words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    line = ["eval", "--est", f"a={tmp_path / 'a.pfm'}", *extra]
    if "--gt" not in extra:
        line += ["--scene", str(tmp_path)]
    assert main(line) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert words in err[0]
