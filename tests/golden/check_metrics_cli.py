#!/usr/bin/python3
"""Scores fresh image pairs, never seen by the tests, with `dejag metrics --json` and with scikit-image,
and prints the largest differences (acceptance check of issue 2; not part of CI, which needs no Python).

    /usr/bin/python3 tests/golden/check_metrics_cli.py [--dejag build/release/dejag] [--count 40] [--seed S]

Exits 1 if any pair differs by more than 1e-4 in SSIM or 1e-3 dB in PSNR.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image, ImageDraw, ImageFilter
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

SSIM_ARGS = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255)


def random_pair(rng):
    h, w = int(rng.integers(11, 300)), int(rng.integers(11, 300))
    channels = int(rng.choice([1, 3, 4]))
    kind = rng.choice(["noise", "shapes", "blur", "gradient", "flat"])
    shape = (h, w) if channels == 1 else (h, w, channels)
    if kind == "noise":
        ref = rng.uniform(0, 255, shape)
        test = ref + rng.normal(0, rng.uniform(1, 40), shape)
    elif kind == "shapes":
        img = Image.new("L", (w * 4, h * 4), int(rng.integers(0, 255)))
        d = ImageDraw.Draw(img)
        for _ in range(8):
            pts = [(float(rng.uniform(0, w * 4)), float(rng.uniform(0, h * 4))) for _ in range(3)]
            d.polygon(pts, fill=int(rng.integers(0, 255)))
        ref = np.asarray(img.resize((w, h), Image.BOX), dtype=np.float64)
        test = np.asarray(img.resize((w, h), Image.NEAREST), dtype=np.float64)
        if channels > 1:
            ref = np.stack([ref * (0.5 + 0.5 * c / channels) for c in range(channels)], -1)
            test = np.stack([test * (0.5 + 0.5 * c / channels) for c in range(channels)], -1)
    elif kind == "blur":
        ref = rng.uniform(0, 255, shape)
        mode = "L" if channels == 1 else ("RGB" if channels == 3 else "RGBA")
        test = np.asarray(Image.fromarray(ref.astype(np.uint8), mode).filter(ImageFilter.GaussianBlur(1.2)),
                          dtype=np.float64)
    elif kind == "gradient":
        yy, xx = np.mgrid[0:h, 0:w]
        g = (xx * 3 + yy * 2) % 256
        ref = g if channels == 1 else np.stack([(g + 40 * c) % 256 for c in range(channels)], -1)
        test = ref + 20 * np.sin(xx / 3.0)[..., None] if channels > 1 else ref + 20 * np.sin(xx / 3.0)
    else:
        ref = np.full(shape, float(rng.integers(0, 255)))
        test = ref + float(rng.integers(-5, 5))
    u8 = lambda a: np.clip(np.rint(a), 0, 255).astype(np.uint8)
    return u8(ref), u8(test), kind


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--dejag", default=os.path.join(os.path.dirname(__file__), "../../build/release/dejag"))
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--seed", type=int, default=int.from_bytes(os.urandom(4), "little"))
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    worst_ssim = worst_psnr = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.count):
            ref, test, kind = random_pair(rng)
            a, b = os.path.join(tmp, f"{i}_ref.png"), os.path.join(tmp, f"{i}_test.png")
            Image.fromarray(ref).save(a)
            Image.fromarray(test).save(b)
            got = json.loads(subprocess.run([args.dejag, "metrics", "--json", a, b], check=True,
                                            capture_output=True, text=True).stdout)
            r, t = ref.astype(np.float64), test.astype(np.float64)
            kw = dict(channel_axis=-1) if r.ndim == 3 else {}
            ssim = structural_similarity(r, t, **SSIM_ARGS, **kw)
            identical = np.array_equal(r, t)
            psnr = math.inf if identical else peak_signal_noise_ratio(r, t, data_range=255)
            d_ssim = abs(got["ssim"] - ssim)
            d_psnr = 0.0 if identical and got["psnr"] is None else abs(got["psnr"] - psnr)
            worst_ssim, worst_psnr = max(worst_ssim, d_ssim), max(worst_psnr, d_psnr)
            print(f"{i:3d} {kind:8s} {ref.shape!s:15s} ssim {ssim:.6f} (diff {d_ssim:.2e})  "
                  f"psnr {psnr:8.4f} (diff {d_psnr:.2e})")
    print(f"seed {args.seed}: {args.count} fresh pairs, max |SSIM diff| {worst_ssim:.3e} (limit 1e-4), "
          f"max |PSNR diff| {worst_psnr:.3e} dB (limit 1e-3)")
    return 0 if worst_ssim <= 1e-4 and worst_psnr <= 1e-3 else 1


if __name__ == "__main__":
    sys.exit(main())
