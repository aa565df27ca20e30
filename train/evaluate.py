"""mAP50 of ONNX detectors on held-out frames, through onnxruntime.

Postprocessing mirrors src/detect (letterbox, score threshold, class-aware
NMS); AP is the all-point interpolated area under the precision/recall curve
per class (VOC 2010+ / COCO-style at IoU 0.5), averaged over classes that have
ground truth.

Two modes per model, both reported:

* ``full``: the whole frame letterboxed into the model's input (one inference);
* ``tiled``: what ``mgmot detect --tile`` does with its defaults: overlapping
  native-resolution tiles of the input's size (overlap 64 px) plus the whole
  frame, merged by class-aware NMS; as src/detect/tiling.rs does, a tile keeps
  only the boxes it sees whole (none within 2 px of a tile edge inside the
  frame) and small (under 32 px in the whole-frame pass's input), the
  whole-frame pass only the others.

Usage: python evaluate.py --models fp32.onnx int8.onnx --data DIR --json out.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort

import data

SCORE_THRESHOLD = 0.001
NMS_IOU = 0.6
MAX_DET = 300


def iou_one_to_many(b, bs):
    ix1, iy1 = np.maximum(b[0], bs[:, 0]), np.maximum(b[1], bs[:, 1])
    ix2, iy2 = np.minimum(b[2], bs[:, 2]), np.minimum(b[3], bs[:, 3])
    inter = np.clip(ix2 - ix1, 0, None) * np.clip(iy2 - iy1, 0, None)
    a = (b[2] - b[0]) * (b[3] - b[1])
    a2 = (bs[:, 2] - bs[:, 0]) * (bs[:, 3] - bs[:, 1])
    return inter / np.maximum(a + a2 - inter, 1e-9)


def decode(out, scale, px, py, x0=0.0, y0=0.0):
    """(4+nc, N) YOLOv8 output -> candidate (boxes x1y1x2y2 in frame pixels, scores, classes)."""
    boxes_c, scores_all = out[:4].T, out[4:].T
    cls = scores_all.argmax(1)
    score = scores_all[np.arange(len(cls)), cls]
    keep = score > SCORE_THRESHOLD
    b, s, c = boxes_c[keep], score[keep], cls[keep]
    xyxy = np.stack([b[:, 0] - b[:, 2] / 2, b[:, 1] - b[:, 3] / 2, b[:, 0] + b[:, 2] / 2, b[:, 1] + b[:, 3] / 2], 1)
    xyxy = (xyxy - np.array([px, py, px, py], np.float32)) / scale + np.array([x0, y0, x0, y0], np.float32)
    return xyxy, s, c


def nms(xyxy, s, c):
    """Class-aware NMS (IoU > NMS_IOU), at most MAX_DET boxes, best score first."""
    order = np.argsort(-s, kind="stable")
    kept = []
    suppressed = np.zeros(len(order), bool)
    for i_pos, i in enumerate(order):
        if suppressed[i_pos]:
            continue
        kept.append(i)
        if len(kept) >= MAX_DET:
            break
        rest = order[i_pos + 1 :]
        same = c[rest] == c[i]
        ious = iou_one_to_many(xyxy[i], xyxy[rest])
        suppressed[i_pos + 1 :] |= same & (ious > NMS_IOU)
    kept = np.asarray(kept, int)
    return xyxy[kept], s[kept], c[kept]


def tile_starts(length, tile, overlap):
    """Same tile placement as src/detect/tiling.rs."""
    if length <= tile:
        return [0]
    step = max(1, tile - overlap)
    span = length - tile
    n = -(-span // step) + 1
    return [i * span // (n - 1) for i in range(n)]


TILE_EDGE_PX = 2.0  # src/detect/tiling.rs TILE_EDGE_MARGIN_PX
WHOLE_FRAME_OBJECT_PX = 32.0  # src/detect/tiling.rs WHOLE_FRAME_OBJECT_PX


def cut_by_tile(xyxy, x0, y0, tw, th, w, h, margin):
    """Boxes of a tile at (x0, y0) that reach one of its edges inside the frame (within
    ``margin`` px): objects the tile cuts in two, seen whole by another tile or the whole-frame
    pass (src/detect/tiling.rs ``keep_from_tile``)."""
    cut = np.zeros(len(xyxy), bool)
    if x0 > 0:
        cut |= xyxy[:, 0] <= x0 + margin
    if y0 > 0:
        cut |= xyxy[:, 1] <= y0 + margin
    if x0 + tw < w:
        cut |= xyxy[:, 2] >= x0 + tw - margin
    if y0 + th < h:
        cut |= xyxy[:, 3] >= y0 + th - margin
    return cut


def detect(sess, inp, size, img, tiled):
    h, w = img.shape[:2]
    views = [(img, 0, 0)]
    if tiled:
        th, tw = size  # src/detect/detector.rs: tiles of the model's input size
        views += [(img[y : y + th, x : x + tw], x, y) for y in tile_starts(h, th, 64) for x in tile_starts(w, tw, 64)]
    parts = []
    for view, x0, y0 in views:
        lb, scale, px, py = data.letterbox(np.ascontiguousarray(view), size)
        out = sess.run(None, {inp.name: data.to_tensor_chw(lb)[None]})[0][0]
        b, s, c = decode(out, scale, px, py, x0, y0)
        if tiled and WHOLE_FRAME_OBJECT_PX > 0 and (view.shape[0], view.shape[1]) == (h, w):
            # ... and the whole-frame pass the large ones.
            whole_scale = min(size[0] / h, size[1] / w)
            keep = np.maximum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]) * whole_scale >= WHOLE_FRAME_OBJECT_PX
            b, s, c = b[keep], s[keep], c[keep]
        if (view.shape[0], view.shape[1]) != (h, w):
            # src/detect/tiling.rs keep_from_tile: a tile keeps the small objects it sees whole.
            keep = np.ones(len(b), bool)
            if TILE_EDGE_PX >= 0:
                keep &= ~cut_by_tile(b, x0, y0, view.shape[1], view.shape[0], w, h, TILE_EDGE_PX)
            if WHOLE_FRAME_OBJECT_PX > 0:
                whole_scale = min(size[0] / h, size[1] / w)
                keep &= np.maximum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]) * whole_scale < WHOLE_FRAME_OBJECT_PX
            b, s, c = b[keep], s[keep], c[keep]
        parts.append((b, s, c))
    return nms(*(np.concatenate(p) for p in zip(*parts)))


def average_precision(recall, precision):
    mrec = np.concatenate([[0.0], recall, [1.0]])
    mpre = np.concatenate([[1.0], precision, [0.0]])
    mpre = np.flip(np.maximum.accumulate(np.flip(mpre)))
    i = np.where(mrec[1:] != mrec[:-1])[0]
    return float(np.sum((mrec[i + 1] - mrec[i]) * mpre[i + 1]))


def map50(preds, gts, nc):
    aps = {}
    for k in range(nc):
        n_gt = sum(int((g[1] == k).sum()) for g in gts)
        if n_gt == 0:
            continue
        recs = []
        for img_i, (pb, ps, pc) in enumerate(preds):
            gb = gts[img_i][0][gts[img_i][1] == k]
            used = np.zeros(len(gb), bool)
            m = pc == k
            for b, s in sorted(zip(pb[m], ps[m]), key=lambda t: -t[1]):
                tp = 0
                if len(gb):
                    ious = iou_one_to_many(b, gb)
                    j = int(np.argmax(ious))
                    if ious[j] >= 0.5 and not used[j]:
                        used[j] = True
                        tp = 1
                recs.append((s, tp))
        recs.sort(key=lambda t: -t[0])
        tps = np.array([t for _, t in recs], float)
        ctp = np.cumsum(tps)
        cfp = np.cumsum(1 - tps)
        recall = ctp / n_gt if len(tps) else np.zeros(0)
        precision = ctp / np.maximum(ctp + cfp, 1e-9) if len(tps) else np.zeros(0)
        aps[k] = average_precision(recall, precision)
    return float(np.mean(list(aps.values()))) if aps else 0.0, aps


CONF_SCORE = 0.25  # the runtime's score threshold (src/detect DEFAULT_SCORE_THRESHOLD)
SMALL_PX = 12.0  # "small": the longer side of the true box under this many pixels


def confusion(preds, gts, nc, score=CONF_SCORE):
    """Confusion counts at IoU 0.5, class-agnostic matching, detections scoring >= ``score``.

    Row = true class (last row: no true object, i.e. a false detection), column =
    detected class (last column: not detected). Each true box is matched to at
    most one detection, greedily by score; the matched pair counts in
    ``[true, detected]``, whatever their classes.
    """
    m = np.zeros((nc + 1, nc + 1), np.int64)
    for (pb, ps, pc), (gb, gc) in zip(preds, gts):
        keep = ps >= score
        pb, ps, pc = pb[keep], ps[keep], pc[keep]
        used = np.zeros(len(gb), bool)
        for i in np.argsort(-ps, kind="stable"):
            j = -1
            if len(gb):
                ious = iou_one_to_many(pb[i], gb)
                ious[used] = 0.0
                j = int(np.argmax(ious))
                if ious[j] < 0.5:
                    j = -1
            if j < 0:
                m[nc, pc[i]] += 1
            else:
                used[j] = True
                m[gc[j], pc[i]] += 1
        for j in np.where(~used)[0]:
            m[gc[j], nc] += 1
    return m


def small_recall(preds, gts, score=CONF_SCORE, small=SMALL_PX):
    """Recall (any class, IoU >= 0.5, score >= ``score``) on true boxes whose longer side is under ``small`` px."""
    hit = total = 0
    for (pb, ps, _), (gb, _) in zip(preds, gts):
        sides = np.maximum(gb[:, 2] - gb[:, 0], gb[:, 3] - gb[:, 1]) if len(gb) else np.zeros(0)
        small_idx = np.where(sides < small)[0]
        total += len(small_idx)
        pb = pb[ps >= score]
        for j in small_idx:
            if len(pb) and iou_one_to_many(gb[j], pb).max() >= 0.5:
                hit += 1
    return (hit / total if total else None), total


def format_confusion(m, names) -> str:
    """The confusion matrix as a Markdown table (rows true, columns detected)."""
    short = [n.replace("life_saving_appliances", "lifesaving") for n in names]
    head = "| true \\ detected | " + " | ".join(short + ["missed"]) + " |"
    rows = [head, "|" + " --- |" * (len(names) + 2)]
    for i, label in enumerate(short + ["(no object)"]):
        rows.append(f"| {label} | " + " | ".join(str(int(v)) for v in m[i]) + " |")
    return "\n".join(rows)


def main():
    global TILE_EDGE_PX, WHOLE_FRAME_OBJECT_PX
    ap = argparse.ArgumentParser()
    ap.add_argument("--models", nargs="+", required=True)
    ap.add_argument("--data", required=True, help="held-out sequences (COCO-style JSON + images)")
    ap.add_argument("--count", type=int, default=0, help="evaluate every k-th frame so that about this many remain (0: all)")
    ap.add_argument("--tiled-every", type=int, default=3, help="tiled mode on every k-th of those frames (5 model runs each at 1280x720)")
    ap.add_argument("--split", default="val", help="split of a SeaDronesSee-layout dataset")
    ap.add_argument("--modes", default="full", help="comma-separated: full (whole frames), tiled")
    ap.add_argument("--threads", type=int, default=1, help="onnxruntime intra-op threads")
    ap.add_argument("--tile-edge-px", type=float, default=TILE_EDGE_PX,
                    help="tiled: drop a tile's boxes within this many px of an edge inside the frame (-1: keep all)")
    ap.add_argument("--tile-large-px", type=float, default=WHOLE_FRAME_OBJECT_PX,
                    help="tiled: objects the whole-frame pass sees at least this long (its model input px) "
                         "are its, smaller ones the tiles' (0: every pass keeps every box)")
    ap.add_argument("--json")
    args = ap.parse_args()
    TILE_EDGE_PX = args.tile_edge_px
    WHOLE_FRAME_OBJECT_PX = args.tile_large_px
    samples = data.load_dataset(Path(args.data), args.split)
    if args.count:
        samples = samples[:: max(1, len(samples) // args.count)]
    frames = [(data.read_image(p), b, c) for p, b, c in samples]
    gts = [(b, c) for _, b, c in frames]
    names = data.class_names()
    report = {
        "frames": len(frames),
        "data": Path(args.data).name,
        "ground_truth_boxes": {names[k]: sum(int((c == k).sum()) for _, c in gts) for k in range(len(names))},
        "models": {},
    }
    for path in args.models:
        so = ort.SessionOptions()
        so.intra_op_num_threads = args.threads  # 1 by default: a loaded 2-core machine punishes spinning threads
        sess = ort.InferenceSession(path, so, providers=["CPUExecutionProvider"])
        inp = sess.get_inputs()[0]
        size = (inp.shape[2], inp.shape[3])
        entry = {}
        for mode in args.modes.split(","):
            k = args.tiled_every if mode == "tiled" else 1
            t0 = time.time()
            preds = [detect(sess, inp, size, img, mode == "tiled") for img, _, _ in frames[::k]]
            dt = time.time() - t0
            m, aps = map50(preds, gts[::k], len(names))
            conf = confusion(preds, gts[::k], len(names))
            rec_small, n_small = small_recall(preds, gts[::k])
            entry[mode] = {
                "frames": len(preds),
                "map50": round(m, 4),
                "ap50_per_class": {names[c]: round(v, 4) for c, v in aps.items()},
                "confusion": {
                    "score_threshold": CONF_SCORE,
                    "rows_true": names + ["(no object)"],
                    "cols_detected": names + ["(missed)"],
                    "counts": conf.tolist(),
                },
                "recall_small": {"max_side_px": SMALL_PX, "score_threshold": CONF_SCORE, "objects": n_small,
                                 "recall": None if rec_small is None else round(rec_small, 4)},
                "ms_per_frame_python_ort": round(1000 * dt / max(1, len(preds)), 2),
            }
            print(f"{path} [{mode}]: mAP50 = {m:.4f} {entry[mode]['ap50_per_class']}; "
                  f"recall < {SMALL_PX:.0f} px: {rec_small} of {n_small}", flush=True)
            print(format_confusion(conf, names), flush=True)
        report["models"][Path(path).name] = entry
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
