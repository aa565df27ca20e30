"""Start TinyDet from the weights of an exported ONNX model (a warm start).

The exported graph has every BatchNorm folded into its convolution
(``W' = W * g / s``, ``b' = beta - g * mu / s``). This puts the folded weights
back into the torch modules and re-creates each BatchNorm so that the network
computes exactly what the ONNX model computes, in eval mode and (on frames like
the calibration ones) in train mode:

1. every ``ConvBnAct``'s convolution gets ``W'``; its BatchNorm starts as
   identity plus the bias ``b'``, so the torch model equals the ONNX model;
2. the convolutions' outputs are measured on a few calibration batches
   (mean ``m`` and variance ``v`` per channel);
3. each BatchNorm gets running statistics ``(m, v)``, weight ``sqrt(v + eps)``
   and bias ``m + b'``: still the same function in eval mode, and batch
   statistics near ``(m, v)`` give the same function in train mode.

Class heads whose class count differs copy the rows of the classes both
models name (by name), the others keep their fresh initialisation. Used by
``train.py --init-onnx``; ``run.sh`` warm-starts from the two-class model
shipped at commit ``8817652`` (see train/README.md).
"""

from __future__ import annotations

import ast

import numpy as np
import onnx
import torch
from onnx import numpy_helper

from model import ConvBnAct


def _module_path(node_name: str) -> str:
    """'/down1/down1.0/conv/Conv' -> 'down1.0.conv' (PyTorch's ONNX scope names)."""
    segs = [s for s in node_name.split("/") if s][:-1]
    path, last = "", ""
    for s in segs:
        if last and s.startswith(last + "."):
            path += s[len(last):]
        else:
            path = f"{path}.{s}" if path else s
        last = s
    return path


def load_onnx_weights(model: torch.nn.Module, onnx_path: str, class_names, calib_batches) -> dict:
    """Loads ``onnx_path``'s weights into ``model`` (see the module doc); returns a summary."""
    proto = onnx.load(onnx_path)
    inits = {i.name: np.array(numpy_helper.to_array(i)) for i in proto.graph.initializer}
    meta = {p.key: p.value for p in proto.metadata_props}
    old_names = list(ast.literal_eval(meta["names"]).values()) if "names" in meta else []
    modules = dict(model.named_modules())
    folded = {}  # ConvBnAct path -> folded bias
    copied = 0
    with torch.no_grad():
        for node in proto.graph.node:
            if node.op_type != "Conv" or len(node.input) < 2:
                continue
            path = _module_path(node.name)
            w = inits.get(node.input[1])
            b = inits.get(node.input[2]) if len(node.input) > 2 else None
            if w is None:
                continue
            conv = modules.get(path)
            if conv is None:
                continue
            parent = path.rsplit(".", 1)[0] if path.endswith(".conv") else None
            if parent is not None and isinstance(modules.get(parent), ConvBnAct):
                conv.weight.copy_(torch.from_numpy(w))
                bn = modules[parent].bn
                bn.weight.fill_(1.0)
                bn.bias.copy_(torch.from_numpy(b) if b is not None else torch.zeros_like(bn.bias))
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
                folded[parent] = bn.bias.clone()
                copied += 1
            elif tuple(conv.weight.shape) == w.shape:
                conv.weight.copy_(torch.from_numpy(w))
                if b is not None and conv.bias is not None:
                    conv.bias.copy_(torch.from_numpy(b))
                copied += 1
            elif conv.weight.shape[1:] == w.shape[1:] and old_names:
                # A class head with other classes: copy the rows of the classes both name.
                for new_k, name in enumerate(class_names):
                    if name in old_names:
                        old_k = old_names.index(name)
                        conv.weight[new_k].copy_(torch.from_numpy(w[old_k]))
                        if b is not None and conv.bias is not None:
                            conv.bias[new_k] = float(b[old_k])
                copied += 1
    # Calibrate: the statistics of every folded convolution's output on real batches.
    stats = {p: [] for p in folded}
    hooks = []
    for p in folded:
        m = modules[p]

        def hook(_mod, inp, _out, p=p):
            y = modules[p].conv(inp[0])
            stats[p].append((y.mean((0, 2, 3)), y.var((0, 2, 3), unbiased=False)))

        hooks.append(m.register_forward_hook(hook))
    model.eval()
    with torch.no_grad():
        for x in calib_batches:
            model(x)
    for h in hooks:
        h.remove()
    with torch.no_grad():
        for p, bias in folded.items():
            if not stats[p]:
                continue
            mean = torch.stack([s[0] for s in stats[p]]).mean(0)
            var = torch.stack([s[1] for s in stats[p]]).mean(0)
            bn = modules[p].bn
            bn.running_mean.copy_(mean)
            bn.running_var.copy_(var)
            bn.weight.copy_(torch.sqrt(var + bn.eps))
            bn.bias.copy_(mean + bias)
    model.train()
    return {"convolutions": copied, "batchnorms": len(folded), "old_classes": old_names}


def check_equal(model: torch.nn.Module, onnx_path: str, x: torch.Tensor) -> float:
    """Largest difference between the torch model (eval, decoded) and the ONNX model on ``x``."""
    import onnxruntime as ort

    sess = ort.InferenceSession(onnx_path, providers=["CPUExecutionProvider"])
    ref = sess.run(None, {sess.get_inputs()[0].name: x.numpy()})[0]
    model.eval()
    model.export_decode = True
    with torch.no_grad():
        out = model(x).numpy()
    model.export_decode = False
    model.train()
    n = min(ref.shape[1], out.shape[1])
    return float(np.abs(ref[:, :4] - out[:, :4]).max()) if n >= 4 else float("nan")
