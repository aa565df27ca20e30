"""Labelled frames for training and evaluation.

Two sources, both deterministic given their seeds:

* ``sim``: sequences rendered by ``mgmot-sim render -s NAME --seed N -o DIR``
  (``img1/*.png`` + ``annotations.json``, SeaDronesSee-style COCO). This is
  the intended source.
* ``procedural``: a stand-in generator used only while mgmot-sim cannot render
  yet: a textured sea with small swimmer blobs and elongated boats. A model
  trained on it is provisional and labelled so in the model card.

A sample is ``(image uint8 HxWx3 RGB, boxes float32 (n, 4) x1 y1 x2 y2 in pixels,
classes int64 (n,))``. Class ids follow ``model.CLASS_NAMES``.
"""

from __future__ import annotations

import json
import math
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
# SeaDronesSee category ids (used by mgmot-sim) when a JSON has no category names.


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


# ---------------------------------------------------------- procedural frames
def procedural_frame(seed: int, width: int = 480, height: int = 320):
    """One synthetic sea frame with swimmers and boats; fully determined by ``seed``."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    base = np.array([20, 60, 80], np.float32) + rng.uniform(-15, 25, 3)
    grad = (yy / height)[..., None] * rng.uniform(-20, 20, 3)
    img = base + grad
    # Waves: a few oriented sinusoids plus noise; sea state scales the amplitude.
    sea_state = rng.uniform(0.2, 1.0)
    for _ in range(4):
        ang = rng.uniform(0, math.pi)
        k = rng.uniform(0.05, 0.4)
        ph = rng.uniform(0, 2 * math.pi)
        img += (10 * sea_state * np.sin(k * (xx * math.cos(ang) + yy * math.sin(ang)) + ph))[..., None]
    img += rng.normal(0, 4 + 6 * sea_state, (height, width, 1))
    # Glints: bright specks that look a little like objects (hard negatives).
    for _ in range(int(40 * sea_state)):
        gx, gy = rng.uniform(0, width), rng.uniform(0, height)
        r = rng.uniform(0.7, 2.0)
        m = ((xx - gx) ** 2 + (yy - gy) ** 2) < r * r
        img[m] = np.clip(img[m] + rng.uniform(60, 140), 0, 255)
    boxes, classes = [], []
    scale = rng.uniform(0.5, 1.6)  # altitude
    for _ in range(rng.integers(0, 7)):  # swimmers: small head/shoulder blobs
        s = rng.uniform(5, 14) * scale
        cx, cy = rng.uniform(s, width - s), rng.uniform(s, height - s)
        ax, ay = s * rng.uniform(0.5, 1.0), s * rng.uniform(0.5, 1.0)
        m = ((xx - cx) / ax) ** 2 + ((yy - cy) / ay) ** 2 < 1
        colour = rng.choice([[220, 170, 140], [90, 60, 40], [240, 120, 20], [230, 200, 40]])
        img[m] = 0.25 * img[m] + 0.75 * np.asarray(colour, np.float32)
        hm = ((xx - cx) / (ax * 0.45)) ** 2 + ((yy - cy + ay * 0.3) / (ay * 0.45)) ** 2 < 1
        img[hm] = np.asarray([60, 40, 30], np.float32)
        boxes.append((cx - ax, cy - ay, cx + ax, cy + ay))
        classes.append(0)
    for _ in range(rng.integers(0, 3)):  # boats: elongated rotated hulls with a wake
        length = rng.uniform(25, 80) * scale
        beam = length * rng.uniform(0.25, 0.4)
        cx, cy = rng.uniform(length / 2, width - length / 2), rng.uniform(length / 2, height - length / 2)
        th = rng.uniform(0, math.pi)
        u = (xx - cx) * math.cos(th) + (yy - cy) * math.sin(th)
        v = -(xx - cx) * math.sin(th) + (yy - cy) * math.cos(th)
        wake = (u < -length / 2) & (u > -length * 1.3) & (np.abs(v) < beam * 0.5 * (1 + (-u - length / 2) / length))
        img[wake] = 0.5 * img[wake] + 0.5 * 235
        hull = (np.abs(u) < length / 2) & (np.abs(v) < beam / 2 * np.clip(1.3 - np.abs(u) / (length / 2) * 0.5, 0, 1))
        colour = rng.choice([[240, 240, 240], [200, 30, 30], [250, 250, 200], [40, 40, 50]])
        img[hull] = np.asarray(colour, np.float32)
        ys, xs = np.nonzero(hull)
        if len(xs):
            boxes.append((xs.min(), ys.min(), xs.max() + 1, ys.max() + 1))
            classes.append(1)
    img = np.clip(img, 0, 255).astype(np.uint8)
    return img, np.asarray(boxes, np.float32).reshape(-1, 4), np.asarray(classes, np.int64)


# ------------------------------------------------------------ preprocessing
def letterbox(img: np.ndarray, size: int, pad_value: int = 114):
    """Resize keeping aspect ratio into size x size, centred; returns (img, scale, pad_x, pad_y).

    Same geometry as the Rust side (src/detect/preprocess.rs).
    """
    h, w = img.shape[:2]
    scale = min(size / w, size / h)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    resized = np.asarray(Image.fromarray(img).resize((nw, nh), Image.BILINEAR))
    out = np.full((size, size, 3), pad_value, np.uint8)
    px, py = (size - nw) // 2, (size - nh) // 2
    out[py : py + nh, px : px + nw] = resized
    return out, scale, px, py


def to_tensor_chw(img: np.ndarray) -> np.ndarray:
    return (img.astype(np.float32) / 255.0).transpose(2, 0, 1)


def class_names():
    return list(CLASS_NAMES)
