"""A small single-stage, anchor-free detector with a YOLOv8-style output.

The network is deliberately tiny (a few hundred thousand parameters) so that it
trains on a 2-core CPU within an hour and runs at well over 15 frames/s on a
companion computer. Its exported ONNX graph has the Ultralytics YOLOv8 / YOLO11
output layout, so the Rust side treats it exactly like a user's YOLOv8 model:

    output[0]: float32 (1, 4 + nc, N)
      rows 0..4: box centre x, centre y, width, height in input pixels
      rows 4.. : per-class scores in [0, 1] (sigmoid applied)
      N = sum over strides (8, 16, 32) of (H / s) * (W / s)

Architecture (YOLOv8-like, ReLU instead of SiLU so that int8 QDQ convolutions
fuse with their activation):
  backbone: strided 3x3 convs and C2f-style blocks down to stride 32
  neck:     top-down FPN (upsample + concat + C2f) to strides 16 and 8
  head:     decoupled per level: box branch -> 4 distances (l, t, r, b),
            class branch -> nc logits
"""

from __future__ import annotations

import torch
from torch import nn
import torch.nn.functional as F

STRIDES = (8, 16, 32)
from classes import CLASS_NAMES  # noqa: E402  (torch-free, shared with data.py)


class ConvBnAct(nn.Module):
    def __init__(self, c_in: int, c_out: int, k: int = 3, s: int = 1):
        super().__init__()
        self.conv = nn.Conv2d(c_in, c_out, k, s, k // 2, bias=False)
        self.bn = nn.BatchNorm2d(c_out)
        self.act = nn.ReLU(inplace=True)

    def forward(self, x):
        return self.act(self.bn(self.conv(x)))


class Bottleneck(nn.Module):
    def __init__(self, c: int):
        super().__init__()
        self.cv1 = ConvBnAct(c, c, 3)
        self.cv2 = ConvBnAct(c, c, 3)

    def forward(self, x):
        return x + self.cv2(self.cv1(x))


class C2f(nn.Module):
    """YOLOv8's C2f block: split, a chain of bottlenecks, concatenate all."""

    def __init__(self, c_in: int, c_out: int, n: int = 1):
        super().__init__()
        self.c = c_out // 2
        self.cv1 = ConvBnAct(c_in, 2 * self.c, 1)
        self.m = nn.ModuleList(Bottleneck(self.c) for _ in range(n))
        self.cv2 = ConvBnAct((2 + n) * self.c, c_out, 1)

    def forward(self, x):
        y = list(self.cv1(x).chunk(2, 1))
        for m in self.m:
            y.append(m(y[-1]))
        return self.cv2(torch.cat(y, 1))


class Head(nn.Module):
    """Decoupled head for one level: box distances and class logits."""

    def __init__(self, c_in: int, c_box: int, c_cls: int, nc: int):
        super().__init__()
        self.box = nn.Sequential(ConvBnAct(c_in, c_box, 3), ConvBnAct(c_box, c_box, 3), nn.Conv2d(c_box, 4, 1))
        self.cls = nn.Sequential(ConvBnAct(c_in, c_cls, 3), ConvBnAct(c_cls, c_cls, 3), nn.Conv2d(c_cls, nc, 1))

    def forward(self, x):
        return self.box(x), self.cls(x)


class TinyDet(nn.Module):
    def __init__(self, nc: int = len(CLASS_NAMES), widths=(16, 32, 48, 64, 96)):
        super().__init__()
        w0, w1, w2, w3, w4 = widths
        self.nc = nc
        self.stem = ConvBnAct(3, w0, 3, 2)  # /2
        self.down1 = nn.Sequential(ConvBnAct(w0, w1, 3, 2), C2f(w1, w1))  # /4
        self.down2 = nn.Sequential(ConvBnAct(w1, w2, 3, 2), C2f(w2, w2))  # /8  -> P3
        self.down3 = nn.Sequential(ConvBnAct(w2, w3, 3, 2), C2f(w3, w3))  # /16 -> P4
        self.down4 = nn.Sequential(ConvBnAct(w3, w4, 3, 2), C2f(w4, w4))  # /32 -> P5
        self.up4 = C2f(w4 + w3, w3)
        self.up3 = C2f(w3 + w2, w2)
        c_box = max(16, w2 // 2)
        c_cls = max(16, w2 // 2)
        self.heads = nn.ModuleList([Head(w2, c_box, c_cls, nc), Head(w3, c_box, c_cls, nc), Head(w4, c_box, c_cls, nc)])
        self.export_decode = False
        prior = -4.6  # sigmoid(-4.6) ~ 0.01: start with few false positives
        for h in self.heads:
            nn.init.constant_(h.cls[-1].bias, prior)
            nn.init.constant_(h.box[-1].bias, 0.5)

    def features(self, x):
        x = self.down1(self.stem(x))
        p3 = self.down2(x)
        p4 = self.down3(p3)
        p5 = self.down4(p4)
        n4 = self.up4(torch.cat([F.interpolate(p5, scale_factor=2.0, mode="nearest"), p4], 1))
        n3 = self.up3(torch.cat([F.interpolate(n4, scale_factor=2.0, mode="nearest"), p3], 1))
        return [n3, n4, p5]

    def raw(self, x):
        """Per level: (box distances in stride units (B, 4, H, W), class logits (B, nc, H, W))."""
        return [h(f) for h, f in zip(self.heads, self.features(x))]

    def forward(self, x):
        outs = self.raw(x)
        if not self.export_decode:
            return outs
        return decode(outs)


def grid_centres(h: int, w: int, stride: int, device=None):
    ys, xs = torch.meshgrid(torch.arange(h, device=device), torch.arange(w, device=device), indexing="ij")
    return (xs.float() + 0.5) * stride, (ys.float() + 0.5) * stride


def distances(box_raw: torch.Tensor, stride: int) -> torch.Tensor:
    """Raw box outputs -> non-negative (l, t, r, b) distances in pixels."""
    return F.softplus(box_raw) * stride


def decode(outs):
    """Raw outputs -> (B, 4 + nc, N) in the YOLOv8 layout (cx, cy, w, h in pixels, class probabilities)."""
    rows = []
    for (box_raw, cls_raw), stride in zip(outs, STRIDES):
        b, _, h, w = box_raw.shape
        gx, gy = grid_centres(h, w, stride, box_raw.device)
        d = distances(box_raw, stride)
        l, t, r, bt = d[:, 0], d[:, 1], d[:, 2], d[:, 3]
        x1, y1, x2, y2 = gx - l, gy - t, gx + r, gy + bt
        box = torch.stack([(x1 + x2) / 2, (y1 + y2) / 2, x2 - x1, y2 - y1], 1)
        rows.append(torch.cat([box, torch.sigmoid(cls_raw)], 1).flatten(2))
    return torch.cat(rows, 2)
