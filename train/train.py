"""Train TinyDet on labelled frames (see data.py), time-bounded and seeded.

Usage: python train.py --data DIR --out ckpt.pt [--minutes 40]

Assignment is FCOS-style centre sampling per pyramid level (a ground-truth box
goes to the levels whose size range holds its longest side; cells near its
centre are positives, the smallest box wins a shared cell). Losses: GIoU on the
decoded boxes of positives and BCE on class logits with an IoU-aware soft
target, normalised by the number of positives.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

import data
from model import STRIDES, TinyDet, distances, grid_centres

# Longest-side range (pixels) of the boxes each level is responsible for.
LEVEL_RANGES = ((0.0, 64.0), (48.0, 160.0), (128.0, 1e9))


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def class_weights(samples, nc: int, power: float) -> np.ndarray:
    """Per-class sampling weight ``(boxes of the commonest class / boxes of the class) ** power`` (0: all 1)."""
    counts = np.zeros(nc)
    for _, _, c in samples:
        counts += np.bincount(c, minlength=nc)[:nc]
    return (counts.max() / np.maximum(counts, 1)) ** power


def random_view(sample, size, rng, weights=None, scales=(0.2, 1.0), whole_frame=0.1, native=0.0, jpeg=(0.0, 85, 85)):
    """One size x size training view of a frame: (image, boxes, classes).

    The frame is scaled by a log-uniform factor in ``scales``: 0.62 is what a
    1280x720 frame looks like letterboxed into the shipped 800x448 input (what
    ``mgmot run`` does by default), 1 is a native-resolution tile (``[detector]
    tile``). 70 % of the views are placed so that they contain the centre of a
    random labelled object (most of a frame is empty sea), the rest anywhere; a
    ``whole_frame`` share are the whole frame letterboxed into the view (objects
    far smaller than the runtime ever sees them: 0.15 at 192 px). A ``native`` share of
    the other views are at scale 1 exactly (what a tile reads). ``jpeg`` (share, qmin,
    qmax): the whole frame is JPEG-encoded at a random quality before it is scaled, as a
    camera encodes at its own resolution (``data.compress_view``).
    """
    path, boxes, classes = sample
    im = Image.open(path)
    if jpeg[0] > 0.0:
        rgb = np.asarray(im.convert("RGB"))
        out = data.compress_view(rgb, rng, *jpeg)
        if out is not rgb:  # compressed; an untouched frame keeps its decoded image
            im = Image.fromarray(out)
    w0, h0 = im.size
    if rng.random() < whole_frame:
        img = np.asarray(im.convert("RGB"))
        out, s, px, py = data.letterbox(img, size)
        return out, boxes * s + np.array([px, py, px, py], np.float32), classes.copy()
    s = 1.0 if rng.random() < native else math.exp(rng.uniform(math.log(scales[0]), math.log(scales[1])))
    nw, nh = max(1, round(w0 * s)), max(1, round(h0 * s))
    im.draft("RGB", (nw, nh))  # JPEG: decode at a reduced DCT scale when possible
    img = np.asarray(im.convert("RGB").resize((nw, nh), Image.BILINEAR))
    b = boxes * np.array([nw / w0, nh / h0, nw / w0, nh / h0], np.float32)
    if len(b) and rng.random() < 0.7:
        if weights is None:
            k = int(rng.integers(0, len(b)))
        else:
            p = weights[classes]
            k = int(rng.choice(len(b), p=p / p.sum()))
        cx, cy = (b[k, 0] + b[k, 2]) / 2, (b[k, 1] + b[k, 3]) / 2
        x0 = int(np.clip(cx - rng.uniform(0.1, 0.9) * size, 0, max(0, nw - size)))
        y0 = int(np.clip(cy - rng.uniform(0.1, 0.9) * size, 0, max(0, nh - size)))
    else:
        x0 = int(rng.integers(0, max(1, nw - size + 1)))
        y0 = int(rng.integers(0, max(1, nh - size + 1)))
    crop = np.full((size, size, 3), 114, np.uint8)
    part = img[y0 : y0 + size, x0 : x0 + size]
    crop[: part.shape[0], : part.shape[1]] = part
    b = b - np.array([x0, y0, x0, y0], np.float32)
    area = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    bc = np.clip(b, 0, [part.shape[1], part.shape[0], part.shape[1], part.shape[0]])
    area_c = (bc[:, 2] - bc[:, 0]) * (bc[:, 3] - bc[:, 1])
    keep = (area_c > 0.5 * np.maximum(area, 1e-6)) & ((bc[:, 2] - bc[:, 0]) >= 2) & ((bc[:, 3] - bc[:, 1]) >= 2)
    return crop, bc[keep], classes[keep]


def augment(img, boxes, rng):
    if rng.random() < 0.5:
        img = img[:, ::-1]
        w = img.shape[1]
        boxes = boxes.copy()
        boxes[:, [0, 2]] = w - boxes[:, [2, 0]]
    if rng.random() < 0.5:
        img = img[::-1]
        h = img.shape[0]
        boxes = boxes.copy()
        boxes[:, [1, 3]] = h - boxes[:, [3, 1]]
    gain = rng.uniform(0.75, 1.25)
    img = np.clip(img.astype(np.float32) * gain + rng.uniform(-15, 15), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(img), boxes


def giou(a, b):
    """GIoU of matching rows of (n, 4) x1y1x2y2 boxes; also returns IoU."""
    ix1, iy1 = torch.max(a[:, 0], b[:, 0]), torch.max(a[:, 1], b[:, 1])
    ix2, iy2 = torch.min(a[:, 2], b[:, 2]), torch.min(a[:, 3], b[:, 3])
    inter = (ix2 - ix1).clamp(min=0) * (iy2 - iy1).clamp(min=0)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a + area_b - inter + 1e-7
    iou = inter / union
    cx1, cy1 = torch.min(a[:, 0], b[:, 0]), torch.min(a[:, 1], b[:, 1])
    cx2, cy2 = torch.max(a[:, 2], b[:, 2]), torch.max(a[:, 3], b[:, 3])
    hull = (cx2 - cx1) * (cy2 - cy1) + 1e-7
    return iou - (hull - union) / hull, iou


def assign(gt_boxes, h, w, stride, level, device):
    """Index of the assigned ground truth per cell (-1 = background) for one image and level."""
    gx, gy = grid_centres(h, w, stride, device)
    gx, gy = gx.flatten(), gy.flatten()
    idx = torch.full((h * w,), -1, dtype=torch.long, device=device)
    if len(gt_boxes) == 0:
        return idx
    lo, hi = LEVEL_RANGES[level]
    bw, bh = gt_boxes[:, 2] - gt_boxes[:, 0], gt_boxes[:, 3] - gt_boxes[:, 1]
    side = torch.max(bw, bh)
    cx, cy = (gt_boxes[:, 0] + gt_boxes[:, 2]) / 2, (gt_boxes[:, 1] + gt_boxes[:, 3]) / 2
    dx = (gx[:, None] - cx[None]).abs()
    dy = (gy[:, None] - cy[None]).abs()
    rx = torch.clamp(bw / 2, min=stride * 1.0).clamp(max=2.5 * stride)
    ry = torch.clamp(bh / 2, min=stride * 1.0).clamp(max=2.5 * stride)
    ok = (dx < rx[None]) & (dy < ry[None]) & ((side >= lo) & (side < hi))[None]
    area = (bw * bh)[None].expand_as(ok)
    cost = torch.where(ok, area, torch.full_like(area, float("inf")))
    best, arg = cost.min(1)
    idx[torch.isfinite(best)] = arg[torch.isfinite(best)]
    return idx


def compute_loss(outs, targets, nc):
    device = outs[0][0].device
    cls_loss = torch.zeros((), device=device)
    box_loss = torch.zeros((), device=device)
    npos = 0
    for level, ((box_raw, cls_raw), stride) in enumerate(zip(outs, STRIDES)):
        b, _, h, w = box_raw.shape
        gx, gy = grid_centres(h, w, stride, device)
        gx, gy = gx.flatten(), gy.flatten()
        d = distances(box_raw, stride).flatten(2)  # (B, 4, HW)
        pred = torch.stack([gx - d[:, 0], gy - d[:, 1], gx + d[:, 2], gy + d[:, 3]], 2)  # (B, HW, 4)
        logits = cls_raw.flatten(2).transpose(1, 2)  # (B, HW, nc)
        target = torch.zeros_like(logits)
        for i, (gtb, gtc) in enumerate(targets):
            idx = assign(gtb, h, w, stride, level, device)
            pos = idx >= 0
            n = int(pos.sum())
            if n == 0:
                continue
            g, io = giou(pred[i][pos], gtb[idx[pos]])
            box_loss = box_loss + (1.0 - g).sum()
            target[i, pos.nonzero().squeeze(1), gtc[idx[pos]]] = io.detach().clamp(min=0.3)
            npos += n
        cls_loss = cls_loss + F.binary_cross_entropy_with_logits(logits, target, reduction="sum")
    n = max(npos, 1)
    return cls_loss / n, box_loss / n


class Batches(torch.utils.data.IterableDataset):
    """Endless training batches, built in a worker process (overlaps JPEG decoding with training).

    Deterministic: one worker, its own generator seeded from ``seed``.
    """

    def __init__(self, samples, crop: int, batch: int, seed: int, balance: float = 0.0, scales=(0.2, 1.0), whole_frame=0.1,
                 jpeg=(0.0, 85, 85), native=0.0):
        super().__init__()
        self.samples, self.crop, self.batch, self.seed = samples, crop, batch, seed
        self.scales, self.whole_frame, self.jpeg, self.native = scales, whole_frame, jpeg, native
        # Rarer classes more often: a frame is drawn in proportion to the weight of its
        # rarest-class object, and the view is centred on an object drawn by class weight.
        self.weights = class_weights(samples, len(data.class_names()), balance) if balance > 0 else None
        if self.weights is not None:
            fw = np.array([self.weights[c].max() if len(c) else 1.0 for _, _, c in samples])
            self.frame_p = fw / fw.sum()

    def __iter__(self):
        rng = np.random.default_rng(self.seed)
        while True:
            imgs, targets = [], []
            for _ in range(self.batch):
                if self.weights is None:
                    i = int(rng.integers(0, len(self.samples)))
                else:
                    i = int(rng.choice(len(self.samples), p=self.frame_p))
                img, boxes, classes = random_view(self.samples[i], self.crop, rng, self.weights, self.scales, self.whole_frame,
                                                  self.native, self.jpeg)
                img, boxes = augment(img, boxes, rng)
                imgs.append(torch.from_numpy(data.to_tensor_chw(img)))
                targets.append((torch.from_numpy(boxes.astype(np.float32)), torch.from_numpy(classes)))
            yield torch.stack(imgs), targets


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True, nargs="+",
                    help="rendered sim sequences, or a SeaDronesSee-layout dataset (see data.py); several folders are pooled")
    ap.add_argument("--split", default="train", help="split of a SeaDronesSee-layout dataset")
    ap.add_argument("--out", required=True)
    ap.add_argument("--crop", type=int, default=256)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--minutes", type=float, default=45.0)
    ap.add_argument("--max-steps", type=int, default=100000)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=1, help="torch threads (the batch loader is one more process)")
    ap.add_argument("--init", help="start from this checkpoint (continue training)")
    ap.add_argument("--init-onnx", help="start from the weights of this exported model (warm_start.py)")
    ap.add_argument("--balance", type=float, default=0.0,
                    help="oversample rare classes: class weight (commonest / class boxes) ** BALANCE (0: off)")
    ap.add_argument("--scales", default="0.2,1.0",
                    help="MIN,MAX: views scale the frame by a log-uniform factor in this range (0.62: the shipped "
                         "800x448 input on a whole 1280x720 frame; 1: native tiles)")
    ap.add_argument("--whole-frame", type=float, default=0.1,
                    help="share of views that are the whole frame letterboxed into the crop")
    ap.add_argument("--jpeg", default="0,85,85",
                    help="SHARE,QMIN,QMAX: JPEG-encode this share of frames at a quality in [QMIN, QMAX] (4:2:0) "
                         "before they are scaled, the rest stay as read; for lossless (PNG) training frames (0: off)")
    ap.add_argument("--native", type=float, default=0.0,
                    help="share of views at scale 1 exactly (a native-resolution tile), the rest log-uniform in --scales")
    args = ap.parse_args()
    try:
        jshare, jqmin, jqmax = (float(v) for v in args.jpeg.split(","))
    except ValueError as e:
        raise SystemExit(f"error: --jpeg wants SHARE,QMIN,QMAX (three numbers), got {args.jpeg!r}") from e
    if not (0.0 <= jshare <= 1.0 and 1 <= jqmin <= jqmax <= 100):
        raise SystemExit(f"error: --jpeg wants 0 <= SHARE <= 1 and 1 <= QMIN <= QMAX <= 100, got {args.jpeg!r}")
    jpeg = (jshare, int(jqmin), int(jqmax))
    if not 0.0 <= args.native <= 1.0:
        raise SystemExit(f"error: --native wants a share in [0, 1], got {args.native}")
    try:
        lo, hi = (float(v) for v in args.scales.split(","))
    except ValueError as e:
        raise SystemExit(f"error: --scales wants MIN,MAX (two numbers), got {args.scales!r}") from e
    if not 0.01 <= lo <= hi <= 4.0:
        raise SystemExit(f"error: --scales wants 0.01 <= MIN <= MAX <= 4, got {args.scales!r}")
    if not 0.0 <= args.whole_frame <= 1.0:
        raise SystemExit(f"error: --whole-frame wants a share in [0, 1], got {args.whole_frame}")

    seed_everything(args.seed)
    torch.set_num_threads(args.threads)
    try:
        samples = [s for d in args.data for s in data.load_dataset(Path(d), args.split)]
    except data.DatasetError as e:
        raise SystemExit(f"error: {e}") from e
    if not samples:
        raise SystemExit(f"no labelled frames found under {args.data}")
    nboxes = sum(len(c) for _, _, c in samples)
    per_class = {n: sum(int((c == k).sum()) for _, _, c in samples) for k, n in enumerate(data.class_names())}
    print(f"{len(samples)} training frames, {nboxes} boxes {per_class}", flush=True)
    model = TinyDet()
    if args.init:
        model.load_state_dict(torch.load(args.init, map_location="cpu")["model"])
        print(f"initialised from {args.init}", flush=True)
    nparams = sum(p.numel() for p in model.parameters())
    print(f"TinyDet: {nparams} parameters", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=5e-4)
    loader = torch.utils.data.DataLoader(
        Batches(samples, args.crop, args.batch, args.seed, args.balance, (lo, hi), args.whole_frame, jpeg, args.native), batch_size=None, num_workers=1, prefetch_factor=4
    )
    batches = iter(loader)
    if args.init_onnx:
        import warm_start

        calib = [next(batches)[0] for _ in range(8)]
        summary = warm_start.load_onnx_weights(model, args.init_onnx, data.class_names(), calib)
        print(f"warm start from {args.init_onnx}: {summary}", flush=True)
    budget_s = args.minutes * 60.0
    t0 = time.time()
    step = 0
    log = []
    model.train()
    while step < args.max_steps:
        elapsed = time.time() - t0
        if elapsed > budget_s:
            break
        # Cosine learning rate over the time budget (warm-up over the first 3 %).
        frac = min(1.0, elapsed / budget_s)
        lr = args.lr * (min(1.0, frac / 0.03) if frac < 0.03 else 0.5 * (1 + math.cos(math.pi * frac)))
        lr = max(lr, args.lr * 0.02)
        for g in opt.param_groups:
            g["lr"] = lr
        x, targets = next(batches)
        outs = model(x)
        lc, lb = compute_loss(outs, targets, model.nc)
        loss = lc + 5.0 * lb
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        opt.step()
        step += 1
        if step % 20 == 0:
            print(f"step {step} t={elapsed:.0f}s lr={lr:.5f} cls={lc.item():.4f} box={lb.item():.4f}", flush=True)
            log.append({"step": step, "t_s": round(elapsed, 1), "cls": lc.item(), "box": lb.item()})
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": model.state_dict(), "args": vars(args), "steps": step, "params": nparams}, args.out)
    Path(args.out).with_suffix(".log.json").write_text(json.dumps({"steps": step, "seconds": time.time() - t0, "log": log}, indent=1))
    print(f"saved {args.out} after {step} steps", flush=True)


if __name__ == "__main__":
    main()
