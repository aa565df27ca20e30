"""Lay simulator sequences out exactly as the SeaDronesSee dataset is laid out.

SeaDronesSee (object detection v2) ships ``images/{train,val}/<id>.jpg`` and
``annotations/instances_{train,val}.json``: COCO with the categories
0 ignored, 1 swimmer, 2 boat, 3 jetski, 4 life_saving_appliances, 5 buoy,
and per image the drone's ``meta`` (latitude, longitude,
height_above_takeoff(meter), gimbal_pitch(degrees), ...) and ``source``.
The simulator's ``annotations.json`` already uses those names and keys, so
this only renumbers images across sequences and copies the files. The result
is what ``train/run.sh`` (``MGMOT_TRAIN_DATA=ROOT``) and ``train.py --data
ROOT`` read as real footage, which is how the path for real data is tested.

Usage: python make_seadronessee_layout.py --out ROOT --split train SEQ_DIR [SEQ_DIR ...]
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

CATEGORIES = [
    {"supercategory": "ignored", "id": 0, "name": "ignored"},
    {"supercategory": "person", "id": 1, "name": "swimmer"},
    {"supercategory": "boat", "id": 2, "name": "boat"},
    {"supercategory": "boat", "id": 3, "name": "jetski"},
    {"supercategory": "object", "id": 4, "name": "life_saving_appliances"},
    {"supercategory": "object", "id": 5, "name": "buoy"},
]


def convert(seqs: list[Path], out: Path, split: str, first_id: int = 1) -> dict:
    """Writes ``out/images/split`` and ``out/annotations/instances_split.json``; returns the document."""
    img_dir = out / "images" / split
    img_dir.mkdir(parents=True, exist_ok=True)
    (out / "annotations").mkdir(parents=True, exist_ok=True)
    doc = {
        "info": {"description": "mgmot-sim renders in the SeaDronesSee layout", "version": "1.0"},
        "licenses": [],
        "categories": CATEGORIES,
        "images": [],
        "annotations": [],
    }
    next_img, next_ann = first_id, 1
    for seq in seqs:
        src = json.loads((seq / "annotations.json").read_text())
        new_id = {}
        for im in src["images"]:
            path = seq / im["file_name"]
            if not path.is_file():
                continue
            name = f"{next_img}{path.suffix}"
            shutil.copyfile(path, img_dir / name)
            new_id[im["id"]] = next_img
            entry = {k: im[k] for k in ("height", "width", "source", "date_time", "meta") if k in im}
            doc["images"].append({"id": next_img, "file_name": name, **entry})
            next_img += 1
        for a in src["annotations"]:
            if a["image_id"] not in new_id:
                continue
            doc["annotations"].append(
                {
                    "id": next_ann,
                    "image_id": new_id[a["image_id"]],
                    "bbox": a["bbox"],
                    "area": a.get("area", a["bbox"][2] * a["bbox"][3]),
                    "category_id": a["category_id"],
                    "iscrowd": 0,
                }
            )
            next_ann += 1
    (out / "annotations" / f"instances_{split}.json").write_text(json.dumps(doc))
    return doc


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--split", default="train")
    ap.add_argument("seqs", nargs="+", type=Path, help="simulator sequence folders (annotations.json + img1/)")
    args = ap.parse_args()
    missing = [s for s in args.seqs if not (s / "annotations.json").is_file()]
    if missing:
        raise SystemExit(f"not a simulator sequence (no annotations.json): {', '.join(map(str, missing))}")
    doc = convert(args.seqs, args.out, args.split)
    print(f"{args.out}: {len(doc['images'])} images, {len(doc['annotations'])} boxes in split {args.split}")


if __name__ == "__main__":
    main()
