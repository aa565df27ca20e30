"""Labelled frames for training and evaluation.

Two layouts are read:

* **simulator sequences**: ``mgmot-sim render -s SCENARIO -o DIR`` writes
  ``img1/*.jpg`` + ``annotations.json`` (SeaDronesSee-style COCO); any folder of
  COCO JSON files next to their images is read the same way
  (:func:`load_coco_dir`);
* **the SeaDronesSee layout** (the real dataset, or one generated in exactly
  its layout by ``make_seadronessee_layout.py``): ``ROOT/images/SPLIT/*.jpg``
  and ``ROOT/annotations/instances_SPLIT.json``, each image with the drone's
  ``meta`` (:func:`load_seadronessee`).

:func:`load_dataset` picks the layout from what is on disk.

A sample is ``(image path, boxes float32 (n, 4) x1 y1 x2 y2 in pixels,
classes int64 (n,))``. Class ids follow ``classes.CLASS_NAMES``. Torch-free.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
from PIL import Image

from classes import CATEGORY_MAP, CLASS_NAMES


class DatasetError(Exception):
    """A dataset that cannot be read as it claims to be (the message says what and where)."""


def _samples_of(doc: dict, image_path, where: str):
    """(path, boxes, classes) of every image of one COCO document whose file exists."""
    if not isinstance(doc, dict) or "images" not in doc or "annotations" not in doc:
        raise DatasetError(f"{where}: not a COCO document (no 'images' / 'annotations')")
    cats = {c["id"]: str(c["name"]).lower() for c in doc.get("categories", [])}
    per_image = {im["id"]: (im, []) for im in doc["images"]}
    for a in doc["annotations"]:
        cls = CATEGORY_MAP.get(cats.get(a.get("category_id"), ""))
        if cls is None or a.get("image_id") not in per_image:
            continue
        x, y, w, h = a["bbox"]
        if w <= 1 or h <= 1:
            continue
        per_image[a["image_id"]][1].append((x, y, x + w, y + h, cls))
    samples, missing = [], 0
    for im, anns in per_image.values():
        path = image_path(im["file_name"])
        if path is None:
            missing += 1
            continue
        arr = np.asarray(anns, dtype=np.float32).reshape(-1, 5)
        samples.append((path, arr[:, :4], arr[:, 4].astype(np.int64)))
    return samples, missing


# ---------------------------------------------------------------- sim frames
def load_coco_dir(root: Path):
    """All (image path, boxes, classes) from every COCO-style JSON under ``root``."""
    samples = []
    for js in sorted(Path(root).rglob("*.json")):
        try:
            doc = json.loads(js.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if not isinstance(doc, dict) or "images" not in doc or "annotations" not in doc:
            continue

        def find(name, base=js.parent):
            path = (base / name).resolve()
            if path.exists():
                return path
            # Look only inside this JSON's folder: every sim sequence numbers its frames from 1.
            cand = list(base.rglob(Path(name).name))
            return cand[0] if cand else None

        samples.extend(_samples_of(doc, find, str(js))[0])
    return samples


# ------------------------------------------------------- SeaDronesSee layout
def is_seadronessee_layout(root: Path) -> bool:
    """True when ``root`` has ``annotations/instances_*.json`` (the SeaDronesSee layout)."""
    return any((Path(root) / "annotations").glob("instances_*.json"))


def load_seadronessee(root: Path, split: str):
    """(image path, boxes, classes) of ``ROOT/annotations/instances_SPLIT.json`` with images in ``ROOT/images/SPLIT``.

    Raises :class:`DatasetError` when the file is missing or unreadable, or when
    none of its images is on disk; images that are missing are skipped and
    counted in the message printed to stdout.
    """
    root = Path(root)
    js = root / "annotations" / f"instances_{split}.json"
    if not js.is_file():
        have = sorted(p.name for p in (root / "annotations").glob("instances_*.json"))
        raise DatasetError(f"{js}: no such file (splits here: {', '.join(have) or 'none'})")
    try:
        doc = json.loads(js.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DatasetError(f"{js}: {e}") from e
    img_dir = root / "images" / split

    def find(name):
        path = img_dir / Path(name).name
        return path if path.is_file() else None

    samples, missing = _samples_of(doc, find, str(js))
    if not samples:
        raise DatasetError(f"{js}: none of its {missing} images is in {img_dir}")
    if missing:
        print(f"{js}: {missing} images not in {img_dir}, skipped", flush=True)
    return samples


def load_dataset(path: Path, split: str = "train"):
    """Samples of ``path``: the SeaDronesSee layout (split ``split``) when it is one, else simulator sequences."""
    path = Path(path)
    if not path.exists():
        raise DatasetError(f"{path}: no such folder")
    if is_seadronessee_layout(path):
        return load_seadronessee(path, split)
    return load_coco_dir(path)


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


def compress_view(img: np.ndarray, rng, share: float, qmin: int, qmax: int) -> np.ndarray:
    """An RGB image (``train.py``: a whole frame, before it is scaled) JPEG-encoded and
    decoded, with probability ``share``, at a quality drawn uniformly from ``[qmin, qmax]``
    with 4:2:0 chroma (as cameras and the renderer encode); otherwise the same array,
    untouched (lossless). ``rng``: a numpy Generator.

    Trained on lossless renders this way, the model sees both a compressed stream and
    an uncompressed one (YUYV / NV12, PNG): one trained on JPEG alone read the missing
    compression at native resolution as other classes (models/README.md).
    """
    if share <= 0.0 or rng.random() >= share:
        return img
    quality = int(rng.integers(qmin, qmax + 1))
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=quality, subsampling=2)
    buf.seek(0)
    return np.asarray(Image.open(buf).convert("RGB"))


def to_tensor_chw(img: np.ndarray) -> np.ndarray:
    return (img.astype(np.float32) / 255.0).transpose(2, 0, 1)


def class_names():
    return list(CLASS_NAMES)
