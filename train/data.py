"""Labelled frames for training and evaluation.

Frames are sequences rendered by ``mgmot-sim render -s SCENARIO --seed N -o DIR``
(``img1/*.jpg`` + ``annotations.json``, SeaDronesSee-style COCO), or any folder
of COCO-style JSON files next to their images (e.g. real footage).

A sample is ``(image uint8 HxWx3 RGB, boxes float32 (n, 4) x1 y1 x2 y2 in pixels,
classes int64 (n,))``. Class ids follow ``model.CLASS_NAMES``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from model import CLASS_NAMES

# Category names in the sim / SeaDronesSee JSON mapped onto our classes; others are ignored.
CATEGORY_MAP = {
    "swimmer": 0,
    "swimmer with life jacket": 0,
    "person": 0,
    "boat": 1,
    "jetski": 1,
}


# ---------------------------------------------------------------- sim frames
def load_coco_dir(root: Path):
    """All (image path, boxes, classes) from every COCO-style JSON under ``root``."""
    samples = []
    for js in sorted(root.rglob("*.json")):
        try:
            doc = json.loads(js.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if not isinstance(doc, dict) or "images" not in doc or "annotations" not in doc:
            continue
        cats = {c["id"]: c["name"].lower() for c in doc.get("categories", [])}
        per_image = {im["id"]: (im, []) for im in doc["images"]}
        for a in doc["annotations"]:
            cls = CATEGORY_MAP.get(cats.get(a["category_id"], ""))
            if cls is None or a["image_id"] not in per_image:
                continue
            x, y, w, h = a["bbox"]
            if w <= 1 or h <= 1:
                continue
            per_image[a["image_id"]][1].append((x, y, x + w, y + h, cls))
        for im, anns in per_image.values():
            path = (js.parent / im["file_name"]).resolve()
            if not path.exists():
                # Look only inside this JSON's folder: every sim sequence numbers its frames from 1.
                cand = list(js.parent.rglob(Path(im["file_name"]).name))
                if not cand:
                    continue
                path = cand[0]
            arr = np.asarray(anns, dtype=np.float32).reshape(-1, 5)
            samples.append((path, arr[:, :4], arr[:, 4].astype(np.int64)))
    return samples


def read_image(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


# ------------------------------------------------------------ preprocessing
def hw(size) -> tuple[int, int]:
    """An input size given as S (square) or (H, W) -> (H, W)."""
    return (size, size) if isinstance(size, int) else (int(size[0]), int(size[1]))


def letterbox(img: np.ndarray, size, pad_value: int = 114):
    """Resize keeping aspect ratio into the input (S x S, or (H, W)), centred; returns (img, scale, pad_x, pad_y).

    Same geometry as the Rust side (src/detect/preprocess.rs).
    """
    out_h, out_w = hw(size)
    h, w = img.shape[:2]
    scale = min(out_w / w, out_h / h)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    resized = np.asarray(Image.fromarray(img).resize((nw, nh), Image.BILINEAR))
    out = np.full((out_h, out_w, 3), pad_value, np.uint8)
    px, py = (out_w - nw) // 2, (out_h - nh) // 2
    out[py : py + nh, px : px + nw] = resized
    return out, scale, px, py


def to_tensor_chw(img: np.ndarray) -> np.ndarray:
    return (img.astype(np.float32) / 255.0).transpose(2, 0, 1)


def class_names():
    return list(CLASS_NAMES)
