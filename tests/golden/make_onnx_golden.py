#!/usr/bin/python3
"""Golden fixtures for the ONNX export of dejag's recurrent ops (warp, accumulate), which Debian 12's
OpenCV (4.6) cannot load: it reads no GatherElements. The independent runtime here is the NumPy evaluator
of tests/golden/check_onnx.py, which implements each ONNX operator from its specification.

Run with Debian's interpreter after a build (`make golden`, or /usr/bin/python3
tests/golden/make_onnx_golden.py [--dejag build/release/dejag]); it needs python3-onnx. It writes
tests/golden/onnx/:
  recurrent_ops.safetensors   a model without parameters: the three warp filters (with whole-pixel,
                              and huge motion) and accumulate with and without the neighbourhood clamp;
  <case>.golden.safetensors   for recurrent_ops and the shipped dejag-temporal: the FNV-1a 64 of the
                              exported graph (so that a changed exporter shows as a stale fixture), the inputs
                              of two steps (F32; dejag-temporal's second step takes the first step's output
                              as its history) and the evaluator's outputs (F64).
The C++ test Onnx.RecurrentExportsMatchTheGoldenEvaluation exports the same models, checks the FNV-1a
and requires Model::forward within 1e-4 of the outputs.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import onnx

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_onnx import evaluate  # noqa: E402
from golden_io import write_safetensors  # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "onnx")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def fnv1a(data):
    h = 0xcbf29ce484222325
    for byte in data:
        h = ((h ^ byte) * 0x100000001b3) & 0xffffffffffffffff
    return f"{h:016x}"


def recurrent_ops_architecture():
    """Input channels: image 0..3, motion 4..5, logits 6..15, history 16..19."""
    def sl(name, frm, to):
        return {"name": name, "op": "slice", "inputs": ["input"], "from": frm, "to": to}
    nodes = [sl("image", 0, 4), sl("motion", 4, 6), sl("logits", 6, 16), sl("history", 16, 20),
             sl("frame", 0, 3)]
    for f in ["bilinear", "catmull-rom", "bicubic"]:
        nodes.append({"name": "warp_" + f, "op": "warp", "inputs": ["image", "motion"], "filter": f})
    nodes.append({"name": "kept", "op": "accumulate", "inputs": ["frame", "logits", "history"], "kernel": 3,
                  "max_count": 32})
    nodes.append({"name": "clipped", "op": "accumulate", "inputs": ["frame", "logits", "history"], "kernel": 3,
                  "max_count": 8, "clip": True})
    nodes.append({"name": "out", "op": "concat",
                  "inputs": ["warp_bilinear", "warp_catmull-rom", "warp_bicubic", "kept", "clipped"]})
    return {"name": "recurrent_ops", "input_channels": 20, "nodes": nodes, "output": "out"}


def write_model_without_parameters(path, architecture):
    metadata = {"dejag.architecture": json.dumps(architecture), "dejag.format": "dejag-model-1",
                "dejag.input_colour": "test values", "dejag.normalisation": "none"}
    text = json.dumps({"__metadata__": metadata}).encode()
    text += b" " * ((8 - (8 + len(text)) % 8) % 8)
    with open(path, "wb") as f:
        f.write(len(text).to_bytes(8, "little"))
        f.write(text)


def recurrent_ops_input(rng, h, w):
    x = np.zeros((1, 20, h, w), np.float32)
    x[0, 0:4] = rng.uniform(0, 1, (4, h, w))
    motion = rng.uniform(-3, 3, (2, h, w))
    motion[:, ::5] = np.round(motion[:, ::5])  # whole pixels
    motion[0, 1, 1], motion[1, 2, 3] = 1e6, -1e6  # far outside: the border
    x[0, 4:6] = motion
    x[0, 6:16] = rng.normal(0, 2, (10, h, w))
    x[0, 16:19] = rng.uniform(0, 1, (3, h, w))
    x[0, 19] = rng.uniform(-0.1, 1.0, (h, w))  # confidence, clamped to [0, N / (N + 1)]
    return x


def temporal_input(rng, h, w, history):
    """dejag-temporal's channels: frame, previous output (shown, kept, confidence), motion, jitter, depth,
    previous depth."""
    x = np.zeros((1, 16, h, w), np.float32)
    x[0, 0:3] = rng.uniform(0, 1, (3, h, w))
    x[0, 3:10] = history
    x[0, 10:12] = rng.uniform(-2.5, 2.5, (2, h, w))
    x[0, 12:14] = rng.uniform(-0.5, 0.5, (2, 1, 1))
    x[0, 14:16] = rng.uniform(0.2, 0.9, (2, h, w))
    return x


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--dejag", default=os.path.join(ROOT, "build/release/dejag"))
    args = parser.parse_args()
    os.makedirs(HERE, exist_ok=True)
    rng = np.random.default_rng(20261207)
    ops_model = os.path.join(HERE, "recurrent_ops.safetensors")
    write_model_without_parameters(ops_model, recurrent_ops_architecture())
    cases = {"recurrent_ops": (ops_model, 16, 8), "dejag_temporal": ("dejag-temporal", 16, 8)}
    with tempfile.TemporaryDirectory() as tmp:
        for case, (model_name, w, h) in cases.items():
            out = os.path.join(tmp, case + ".onnx")
            subprocess.run([args.dejag, "export", "--onnx", model_name, out, "--size", f"{w}x{h}"], check=True,
                           stdout=subprocess.DEVNULL)
            model = onnx.load(out)
            # The graph alone (the file's metadata name the version and the source file).
            data = model.graph.SerializeToString()
            onnx.checker.check_model(model, full_check=True)
            onnx.shape_inference.infer_shapes(model, strict_mode=True)
            tensors = {}
            if case == "recurrent_ops":
                steps = [recurrent_ops_input(rng, h, w) for _ in range(2)]
                outputs = [evaluate(model, x) for x in steps]
            else:
                first = np.zeros((7, h, w), np.float32)
                first[0:6] = rng.uniform(0, 1, (6, h, w))
                first[6] = rng.uniform(0, 0.97, (h, w))
                steps = [temporal_input(rng, h, w, first)]
                outputs = [evaluate(model, steps[0])]
                steps.append(temporal_input(rng, h, w, outputs[0][0].astype(np.float32)))
                outputs.append(evaluate(model, steps[1]))
            for i, (x, y) in enumerate(zip(steps, outputs)):
                tensors[f"input{i}"] = x
                tensors[f"output{i}"] = y.astype(np.float64)
            config = {"model": model_name if case != "recurrent_ops" else "tests/golden/onnx/recurrent_ops.safetensors",
                      "width": w, "height": h, "graph_fnv1a": fnv1a(data), "nodes": len(model.graph.node)}
            write_safetensors(os.path.join(HERE, case + ".golden.safetensors"), tensors, config)
            print(f"{case}: {len(model.graph.node)} nodes, checker and strict shape inference pass, "
                  f"outputs {[tuple(y.shape) for y in outputs]}")


if __name__ == "__main__":
    main()
