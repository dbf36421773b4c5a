"""Scoring as `dejag train export` scores, for the analysis scripts (scripts/blend-oracle,
scripts/sample-count-bound): the first three colour channels sRGB-encoded and clamped to [0, 1], PSNR
per image with data range 1, capped at 100 dB, averaged over images (data/evaluation.cpp).

Needs numpy and OpenImageIO's Python module (scripts/install-deps --analysis); Debian's /usr/bin/python3
owns them.
"""
import json
import os
import sys

try:
    import numpy as np
    import OpenImageIO as oiio
except ImportError as e:
    sys.exit(f"{os.path.basename(sys.argv[0])}: the Python module {e.name} is missing "
             "(scripts/install-deps --analysis; run with /usr/bin/python3)")

PSNR_CAP = 100.0  # one perfect image must not swamp the mean


def fail(message):
    sys.exit(f"{os.path.basename(sys.argv[0])}: {message}")


def read_manifest(folder):
    """The records of a dataset's manifest.jsonl (dejag data generate)."""
    path = os.path.join(folder, "manifest.jsonl")
    if not os.path.isfile(path):
        fail(f"'{folder}' is not a dataset (no manifest.jsonl; make dataset)")
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def read_rgb(path):
    """The R, G and B channels of an image file, by name, as float64 (H, W, 3)."""
    image = oiio.ImageInput.open(path)
    if image is None:
        fail(f"cannot read '{path}': {oiio.geterror()}")
    spec = image.spec()
    pixels = image.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
    image.close()
    names = list(spec.channelnames)
    if not all(c in names for c in "RGB"):
        fail(f"'{path}' has no R, G and B channels ({', '.join(names)})")
    pixels = np.asarray(pixels, dtype=np.float64).reshape(spec.height, spec.width, spec.nchannels)
    return pixels[:, :, [names.index(c) for c in "RGB"]]


def srgb_encoded(linear):
    x = np.maximum(linear, 0.0)
    return np.clip(np.where(x <= 0.0031308, x * 12.92, 1.055 * np.power(x, 1 / 2.4) - 0.055), 0.0, 1.0)


def psnr(mse):
    return PSNR_CAP if mse <= 0 else min(10 * np.log10(1.0 / mse), PSNR_CAP)


def image_psnr(image, truth):
    """PSNR of one sRGB-encoded image against another, over all pixels and channels."""
    return psnr(float(((image - truth) ** 2).mean()))
