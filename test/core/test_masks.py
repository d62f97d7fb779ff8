"""One rule for masks (``inside_mask``): boolean, 0/1, or an official mask image, else refused.

A MiddEval3 ``mask0nocc.png`` is 255 non-occluded, 128 occluded, 0 no GT: read as it is and
passed to the evaluator, the occluded pixels must land in ``occluded``, never in ``nonocc`` (a
truthy test put them there and gave ``occluded n 0``).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from dispeval_ros import Evaluator
from dispeval_ros.cli.main import main
from dispeval_ros.core.criteria import inside_mask
from dispeval_ros.core.protocols import FrameData, evaluate_frame
from dispeval_ros.errors import InputError
from dispeval_ros.io import load_scene, read_disparity, read_mask, write_pfm

MIDDEVAL3 = "middeval3-training-Q"
SCENES = ("Adirondack", "Jadeplant", "Teddy")


def _noisy(gt: np.ndarray) -> np.ndarray:
    noise = np.random.default_rng(3).normal(0.0, 1.0, gt.shape).astype(np.float32)
    return np.where(np.isfinite(gt), gt + noise, np.inf).astype(np.float32)


@pytest.mark.parametrize("name", SCENES)
def test_middeval3_mask_as_read_puts_occluded_pixels_in_occluded(
    shared_data: Path, name: str
) -> None:
    folder = shared_data / MIDDEVAL3 / name
    gt = read_disparity(folder / "disp0GT.pfm")
    raw = read_mask(folder / "mask0nocc.png")
    assert set(np.unique(raw)) == {0, 128, 255}
    valid = np.isfinite(gt) & (gt > 0)
    expected = int(np.count_nonzero(valid & (raw != 255)))
    assert expected > 0
    ev = Evaluator(criteria=("visibility",))
    as_read = ev.score(gt, _noisy(gt), masks={"nonocc": raw})
    as_bool = ev.score(gt, _noisy(gt), masks={"nonocc": raw == 255})
    assert as_read["occluded"]["n"] == expected
    assert dict(as_read["occluded"]) == dict(as_bool["occluded"])
    assert np.array_equal(load_scene(folder).masks["nonocc"], raw == 255)


def test_middeval3_protocol_takes_the_mask_as_read_or_boolean(shared_data: Path) -> None:
    folder = shared_data / MIDDEVAL3 / "Teddy"
    gt = read_disparity(folder / "disp0GT.pfm")
    raw = read_mask(folder / "mask0nocc.png")
    est = _noisy(gt)
    official = evaluate_frame("middeval3", FrameData("Teddy", gt, nonocc_mask=raw), est)
    boolean = evaluate_frame("middeval3", FrameData("Teddy", gt, nonocc_mask=raw == 255), est)
    assert official.values["nonocc"] == boolean.values["nonocc"]
    assert official.values["nonocc"] != official.values["all"]


@pytest.mark.parametrize(
    ("values", "inside"),
    [
        (np.array([[True, False]]), [True, False]),
        (np.array([[1, 0]], np.uint8), [True, False]),
        (np.array([[1.0, 0.0]]), [True, False]),
        (np.array([[255, 128, 0]], np.uint8), [True, False, False]),
        (np.array([[255, 255]], np.int32), [True, True]),
    ],
)
def test_accepted_conventions(values: np.ndarray, inside: list[bool]) -> None:
    assert inside_mask("m", values).tolist() == [inside]


@pytest.mark.parametrize(
    "values",
    [
        np.array([[0, 1, 255]], np.uint8),  # two conventions at once
        np.array([[0, 64, 255]], np.uint8),  # a grey level no convention uses
        np.array([[0.5, 1.0]]),
        np.array([["a", "b"]]),
    ],
)
def test_ambiguous_masks_are_refused_naming_the_mask(values: np.ndarray) -> None:
    gt = np.full(values.shape, 10.0, np.float32)
    with pytest.raises(InputError, match="the 'nonocc' mask"):
        Evaluator(criteria=("visibility",)).score(gt, gt, masks={"nonocc": values})


def test_cli_refuses_an_ambiguous_mask_file_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = np.tile(np.linspace(10, 40, 32, dtype=np.float32), (24, 1))
    write_pfm(tmp_path / "gt.pfm", gt)
    mask = np.full(gt.shape, 255, np.uint8)
    mask[:, :4] = 60
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    code = main(
        [
            "eval",
            "--gt",
            str(tmp_path / "gt.pfm"),
            "--est",
            f"a={tmp_path / 'gt.pfm'}",
            "--mask",
            f"nonocc={tmp_path / 'mask.png'}",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert "mask.png (--mask nonocc) holds the values 60, 255" in err
    assert "Traceback" not in err
