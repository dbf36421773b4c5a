#!/usr/bin/python3
"""Checks `dejag export --onnx` with tools dejag does not contain (not part of CI, which needs no Python):

1. python3-onnx's checker (full check) and strict shape inference on every shipped model,
   exported at a symbolic size and at a fixed one;
2. the symbolic export of dejag-fast run by a small NumPy evaluator of the ONNX operators written here
   (independent of dejag's kernels), against `dejag filter --method cnn --gate off --precision fp32` on a
   rendered frame: the largest difference is printed (the C++ test Onnx.* checks the fixed-size exports
   against OpenCV's DNN module, which cannot run a symbolic size);
3. the symbolic export of dejag-temporal run the same way on a rendered sequence, its input assembled per
   frame as docs/onnx.md says, against `dejag filter --method cnn-temporal` with the still gate off.

    /usr/bin/python3 tests/golden/check_onnx.py [--dejag build/release/dejag]

Exits 1 on a checker error or a difference above 1e-4.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import onnx
import onnx.numpy_helper
import onnx.shape_inference
import OpenImageIO as oiio

MODELS = ["dejag-fast", "dejag-guided", "seed2020-gray", "dejag-temporal"]


def srgb_encode(x):
    x = np.clip(x, 0, None)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def conv(x, w, b, strides, pads, dilations):
    n, c, h, wd = x.shape
    co, ci, kh, kw = w.shape
    xp = np.pad(x, ((0, 0), (0, 0), (pads[0], pads[2]), (pads[1], pads[3])))
    oh = (xp.shape[2] - dilations[0] * (kh - 1) - 1) // strides[0] + 1
    ow = (xp.shape[3] - dilations[1] * (kw - 1) - 1) // strides[1] + 1
    out = np.zeros((n, co, oh, ow), np.float64)
    for i in range(kh):
        for j in range(kw):
            patch = xp[:, :, i * dilations[0]: i * dilations[0] + strides[0] * (oh - 1) + 1: strides[0],
                       j * dilations[1]: j * dilations[1] + strides[1] * (ow - 1) + 1: strides[1]]
            out += np.einsum("nchw,oc->nohw", patch, w[:, :, i, j])
    if b is not None:
        out += b[None, :, None, None]
    return out


def same_upper(size, k, s, d):
    out = -(-size // s)
    total = max(0, (out - 1) * s + d * (k - 1) + 1 - size)
    return total // 2, total - total // 2


def reshape(x, dims):
    dims = [int(x.shape[i]) if d == 0 else int(d) for i, d in enumerate(dims)]
    return x.reshape(dims)


def evaluate(model, x, everything=False):
    """Runs the graph on x in double precision: the operators dejag's exports use, as the ONNX operator
    specification defines them (integer tensors stay int64)."""
    values = {"input": x.astype(np.float64)}
    for init in model.graph.initializer:
        values[init.name] = onnx.numpy_helper.to_array(init).astype(np.float64) \
            if init.data_type == onnx.TensorProto.FLOAT else onnx.numpy_helper.to_array(init)
    for node in model.graph.node:
        a = {attr.name: onnx.helper.get_attribute_value(attr) for attr in node.attribute}
        ins = [values[i] if i else None for i in node.input]
        op = node.op_type
        if op == "Conv":
            w = ins[1]
            k, s, d = a["kernel_shape"], a.get("strides", [1, 1]), a.get("dilations", [1, 1])
            if a.get("auto_pad", b"NOTSET") == b"SAME_UPPER":
                t, bt = same_upper(ins[0].shape[2], k[0], s[0], d[0])
                l, r = same_upper(ins[0].shape[3], k[1], s[1], d[1])
                pads = [t, l, bt, r]
            else:
                pads = a.get("pads", [0, 0, 0, 0])
            y = conv(ins[0], w, ins[2] if len(ins) > 2 else None, s, pads, d)
        elif op == "Relu":
            y = np.maximum(ins[0], 0)
        elif op == "LeakyRelu":
            y = np.where(ins[0] < 0, a.get("alpha", 0.01) * ins[0], ins[0])
        elif op == "Sigmoid":
            y = 1 / (1 + np.exp(-ins[0]))
        elif op in ("Add", "Sub", "Mul", "Div", "Pow", "Greater"):
            y = {"Add": np.add, "Sub": np.subtract, "Mul": np.multiply, "Div": np.divide, "Pow": np.power,
                 "Greater": np.greater}[op](ins[0], ins[1])
        elif op in ("Min", "Max"):
            y = ins[0]
            for other in ins[1:]:
                y = (np.minimum if op == "Min" else np.maximum)(y, other)
        elif op in ("Neg", "Floor", "IsNaN"):
            y = {"Neg": np.negative, "Floor": np.floor, "IsNaN": np.isnan}[op](ins[0])
        elif op == "Where":
            y = np.where(ins[0], ins[1], ins[2])
        elif op == "Cast":
            y = ins[0].astype({onnx.TensorProto.FLOAT: np.float64, onnx.TensorProto.INT64: np.int64}[a["to"]])
        elif op == "Shape":
            y = np.array(ins[0].shape, np.int64)
        elif op == "Gather":
            y = np.take(ins[0], ins[1], axis=a.get("axis", 0))
        elif op == "Range":
            y = np.arange(ins[0], ins[1], ins[2])
        elif op == "Reshape":
            y = reshape(ins[0], ins[1])
        elif op == "Expand":
            y = np.broadcast_to(ins[0], np.broadcast_shapes(ins[0].shape, tuple(int(d) for d in ins[1])))
        elif op == "GatherElements":
            y = np.take_along_axis(ins[0], ins[1], axis=a.get("axis", 0))
        elif op == "Concat":
            y = np.concatenate(ins, axis=a["axis"])
        elif op == "DepthToSpace":
            b = a["blocksize"]
            n, c, h, w = ins[0].shape
            y = ins[0].reshape(n, c // (b * b), b, b, h, w).transpose(0, 1, 4, 2, 5, 3).reshape(
                n, c // (b * b), h * b, w * b)
        elif op == "Slice":
            y = ins[0]
            for start, end, axis in zip(ins[1], ins[2], ins[3]):
                index = [slice(None)] * y.ndim
                index[int(axis)] = slice(int(start), None if end >= 2**62 else int(end))
                y = y[tuple(index)]
        elif op == "Softmax":
            e = np.exp(ins[0] - ins[0].max(axis=a["axis"], keepdims=True))
            y = e / e.sum(axis=a["axis"], keepdims=True)
        elif op == "Pad":
            p = ins[1]
            half = len(p) // 2
            y = np.pad(ins[0], [(int(p[i]), int(p[i + half])) for i in range(half)], mode="edge")
        elif op == "Identity":
            y = ins[0]
        else:
            raise SystemExit(f"check_onnx: no evaluator for {op}")
        values[node.output[0]] = y
    return values if everything else values[model.graph.output[0].name]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--dejag", default="build/release/dejag")
    args = parser.parse_args()
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for name in MODELS:
            for size in [None, "64x48"]:
                out = os.path.join(tmp, f"{name}-{size or 'symbolic'}.onnx")
                subprocess.run([args.dejag, "export", "--onnx", name, out] + (["--size", size] if size else []),
                               check=True, stdout=subprocess.DEVNULL)
                model = onnx.load(out)
                try:
                    onnx.checker.check_model(model, full_check=True)
                    onnx.shape_inference.infer_shapes(model, strict_mode=True)
                    print(f"{name} ({size or 'symbolic'}): checker and strict shape inference pass, "
                          f"{len(model.graph.node)} nodes")
                except Exception as error:  # noqa: BLE001 - report and go on
                    print(f"{name} ({size or 'symbolic'}): {error}")
                    failed = True

        # dejag-fast at a symbolic size, on a rendered frame, against dejag's own filter.
        render = os.path.join(tmp, "render")
        subprocess.run([args.dejag, "render", "--scene", "pipe", "--size", "136x80", "--out", render, "--quiet"],
                       check=True)
        frame = os.path.join(render, "frame_0000.exr")
        filtered = os.path.join(tmp, "filtered.exr")
        subprocess.run([args.dejag, "filter", "--method", "cnn", "--gate", "off", "--precision", "fp32",
                        "--quiet", frame, filtered], check=True)
        rgb = oiio.ImageBuf(frame).get_pixels(oiio.FLOAT)[:, :, :3]
        x = srgb_encode(rgb.astype(np.float64)).transpose(2, 0, 1)[None]
        model = onnx.load(os.path.join(tmp, "dejag-fast-symbolic.onnx"))
        y = evaluate(model, x)[0].transpose(1, 2, 0)
        expected = srgb_encode(oiio.ImageBuf(filtered).get_pixels(oiio.FLOAT)[:, :, :3].astype(np.float64))
        difference = float(np.abs(np.clip(y, 0, 1) - expected).max())
        print(f"dejag-fast (symbolic) in NumPy against dejag filter on a 136x80 frame: largest difference "
              f"{difference:.3g}")
        failed |= difference > 1e-4

        # dejag-temporal at a symbolic size on a rendered sequence, its input assembled per frame as
        # docs/onnx.md says, against `dejag filter --method cnn-temporal` (the still gate off).
        seq = os.path.join(tmp, "seq")
        subprocess.run([args.dejag, "render", "--scene", "hairball-rotating", "--size", "96x64", "--frames", "5",
                        "--jitter", "halton16", "--buffers", "color,depth,motion,prevdepth", "--out", seq,
                        "--quiet"], check=True)
        out = os.path.join(tmp, "seq_out")
        subprocess.run([args.dejag, "filter", "--method", "cnn-temporal", "--set", "gate=off", "--set",
                        "precision=fp32", "--quiet", os.path.join(seq, "frame_%04d.exr"),
                        os.path.join(out, "frame_%04d.exr")], check=True)
        info = json.load(open(os.path.join(seq, "render.json")))
        model = onnx.load(os.path.join(tmp, "dejag-temporal-symbolic.onnx"))
        previous = None
        worst = 0.0
        for frame in info["frames"]:
            buf = oiio.ImageBuf(os.path.join(seq, frame["file"]))
            names = list(buf.spec().channelnames)
            pixels = buf.get_pixels(oiio.FLOAT).astype(np.float64)
            plane = lambda name: pixels[:, :, names.index(name)]  # noqa: E731
            rgb = srgb_encode(pixels[:, :, :3]).transpose(2, 0, 1)
            h, w = rgb.shape[1:]
            x = np.zeros((1, 16, h, w))
            x[0, 0:3] = rgb
            if previous is None:
                x[0, 3:6] = rgb
            else:
                x[0, 3:10] = previous
                x[0, 10] = plane("motion.X")
                x[0, 11] = plane("motion.Y")
            x[0, 12] = frame["jitter_pixels"][0]
            x[0, 13] = frame["jitter_pixels"][1]
            x[0, 14] = plane("depth.Z") / info["depth_far"]
            x[0, 15] = x[0, 14] if previous is None else plane("prevdepth.Z") / info["depth_far"]
            y = evaluate(model, x.astype(np.float32))[0]
            previous = y
            got = oiio.ImageBuf(os.path.join(out, frame["file"])).get_pixels(oiio.FLOAT)[:, :, :3]
            worst = max(worst, float(np.abs(np.clip(y[0:3], 0, 1).transpose(1, 2, 0)
                                            - srgb_encode(got.astype(np.float64))).max()))
        print(f"dejag-temporal (symbolic) in NumPy, 5 frames of a 96x64 sequence, input assembled as "
              f"docs/onnx.md says, against dejag filter --method cnn-temporal: largest difference {worst:.3g}")
        failed |= worst > 1e-4
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
