"""Tests of the torch-free data path of train/: the SeaDronesSee-layout loader and converter.

Run: ``python train/test_data.py SIM_SEQUENCE_DIR`` (a folder written by
``mgmot-sim render ... --format jpg``; scripts/test.sh renders a short one).
Needs numpy and Pillow only. Exits non-zero on the first failure.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import data  # noqa: E402
import make_seadronessee_layout as layout  # noqa: E402
from classes import CLASS_NAMES  # noqa: E402


def check(cond, what):
    if not cond:
        raise SystemExit(f"FAIL: {what}")
    print(f"ok: {what}")


def check_compress_view(img):
    """Stage 5's augmentation: lossless or JPEG at a random quality, same shape, deterministic."""
    import numpy as np

    view = np.ascontiguousarray(img[:192, :192])
    same = data.compress_view(view, np.random.default_rng(1), 0.0, 40, 100)
    check(same is view, "share 0 leaves every view lossless")
    low = data.compress_view(view, np.random.default_rng(1), 1.0, 10, 10)
    check(low.shape == view.shape and low.dtype == np.uint8, f"a compressed view keeps its shape ({low.shape})")
    err = float(np.abs(low.astype(np.int16) - view.astype(np.int16)).mean())
    check(err > 0.5, f"quality 10 changes the pixels (mean abs difference {err:.2f})")
    near = data.compress_view(view, np.random.default_rng(1), 1.0, 100, 100)
    err100 = float(np.abs(near.astype(np.int16) - view.astype(np.int16)).mean())
    check(err100 < err, f"quality 100 changes them less than 10 ({err100:.2f} < {err:.2f})")
    a = [data.compress_view(view, np.random.default_rng(7), 0.5, 40, 100) for _ in range(2)]
    check((a[0] == a[1]).all(), "the same generator seed gives the same view")
    kept = sum(data.compress_view(view, g, 0.67, 40, 100) is view for g in (np.random.default_rng(s) for s in range(300)))
    check(70 <= kept <= 130, f"share 0.67 leaves about a third lossless ({kept} of 300)")


def main():
    seq = Path(sys.argv[1])
    sim = data.load_coco_dir(seq)
    check(len(sim) > 0, f"the simulator sequence {seq} has labelled frames ({len(sim)})")
    sim_classes = sorted({int(c) for _, _, cs in sim for c in cs})
    check(len(sim_classes) >= 3, f"the sequence shows at least three classes ({[CLASS_NAMES[c] for c in sim_classes]})")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "sds"
        layout.convert([seq], root, "train")
        layout.convert([seq], root, "val")
        check((root / "annotations" / "instances_train.json").is_file(), "the layout has annotations/instances_train.json")
        doc = json.loads((root / "annotations" / "instances_val.json").read_text())
        check([c["name"] for c in doc["categories"]] == ["ignored", *CLASS_NAMES], "the categories are SeaDronesSee's, in its order")
        meta = doc["images"][0]["meta"]
        for key in ("latitude", "longitude", "height_above_takeoff(meter)", "gimbal_pitch(degrees)", "compass_heading(degrees)"):
            check(key in meta, f"images carry SeaDronesSee's meta key {key!r}")
        check(data.is_seadronessee_layout(root), "the layout is recognised")
        sds = data.load_dataset(root, "train")
        check(len(sds) == len(sim), f"every frame is read back ({len(sds)} of {len(sim)})")
        # The same boxes and classes, frame by frame (both lists follow the image order).
        for (p1, b1, c1), (p2, b2, c2) in zip(sim, sds):
            check_same = b1.shape == b2.shape and (abs(b1 - b2) < 1e-3).all() and (c1 == c2).all()
            if not check_same:
                raise SystemExit(f"FAIL: boxes of {p1} and {p2} differ")
        check(True, "boxes and classes match the simulator's frame by frame")
        img = data.read_image(sds[0][0])
        check(img.ndim == 3 and img.shape[2] == 3, f"images decode as RGB ({img.shape})")
        check_compress_view(img)
        # Bad input is refused with a message that says what is wrong.
        try:
            data.load_seadronessee(root, "test")
            check(False, "a missing split is refused")
        except data.DatasetError as e:
            check("instances_test.json" in str(e) and "instances_train.json" in str(e), f"a missing split is refused: {e}")
        for f in (root / "images" / "val").iterdir():
            f.unlink()
        try:
            data.load_seadronessee(root, "val")
            check(False, "a split without images is refused")
        except data.DatasetError as e:
            check("none of its" in str(e), f"a split without images is refused: {e}")
        try:
            data.load_dataset(Path(tmp) / "nothing")
            check(False, "a missing folder is refused")
        except data.DatasetError as e:
            check("no such folder" in str(e), f"a missing folder is refused: {e}")
    print("all train/ data tests passed")


if __name__ == "__main__":
    main()
