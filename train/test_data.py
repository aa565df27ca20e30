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
