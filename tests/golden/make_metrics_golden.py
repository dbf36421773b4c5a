#!/usr/bin/python3
"""Golden files for dejag's image metrics, scored by scikit-image (the independent reference).

Run with Debian's interpreter (`make golden`, or /usr/bin/python3 tests/golden/make_metrics_golden.py);
it needs python3-skimage and python3-pil. It writes, next to itself in metrics/:
  <case>_ref.png, <case>_test.png   image pairs this script generates (noise, edges, flat, gradients,
                                     text, colour, odd sizes, 16-bit, alpha)
  expected.json                     per case: MSE, RMSE, PSNR, SNR, SSIM (mean and per channel)
  edges_ssim_map.f32                the full per-pixel SSIM map of one grey case (float32, row-major)
SSIM settings are docs/metrics.md's: gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
data_range = 255 for 8-bit and 65535 for 16-bit. The C++ tests (tests/data/metrics_golden_test.cpp)
read these files, so CI needs no Python.
"""
import json
import math
import os

import numpy as np
from PIL import Image, ImageDraw, ImageFilter, ImageFont
from skimage.metrics import mean_squared_error, peak_signal_noise_ratio, structural_similarity

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "metrics")
SSIM_ARGS = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False)


def to_u8(a):
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def make_cases(rng):
    cases = {}
    h, w = 72, 96

    # Noise: a textured image against itself plus Gaussian noise.
    base = rng.uniform(0, 255, (h, w, 3))
    cases["noise"] = (to_u8(base), to_u8(base + rng.normal(0, 12, base.shape)))

    # Edges: aliased (binary) shapes against the same shapes supersampled 8x8 (anti-aliased).
    def shapes(scale):
        img = Image.new("L", (w * scale, h * scale), 30)
        d = ImageDraw.Draw(img)
        d.polygon([(5 * scale, 60 * scale), (40 * scale, 8 * scale), (70 * scale, 55 * scale)], fill=220)
        d.line([(0, 70 * scale), (95 * scale, 20 * scale)], fill=160, width=2 * scale)
        d.ellipse([60 * scale, 10 * scale, 90 * scale, 40 * scale], fill=100)
        return img

    aliased = np.asarray(shapes(1), dtype=np.float64)
    truth = np.asarray(shapes(8).resize((w, h), Image.BOX), dtype=np.float64)
    cases["edges"] = (to_u8(truth), to_u8(aliased))

    # Flat: constant images (zero variance everywhere), grey and colour.
    cases["flat"] = (np.full((h, w), 128, np.uint8), np.full((h, w), 131, np.uint8))
    cases["flat_colour"] = (np.full((h, w, 3), (10, 200, 90), np.uint8), np.full((h, w, 3), (12, 197, 90), np.uint8))

    # Gradients: smooth ramps against a coarsely quantised, slightly shifted version.
    yy, xx = np.mgrid[0:h, 0:w]
    ramp = np.stack([xx * 255.0 / (w - 1), yy * 255.0 / (h - 1), (xx + yy) * 255.0 / (w + h - 2)], axis=-1)
    cases["gradients"] = (to_u8(ramp), to_u8(np.floor((ramp + 6) / 24) * 24))

    # Text: letters drawn sharp against the same text blurred and moved by a pixel.
    img = Image.new("RGB", (w * 2, h), (240, 240, 230))
    d = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    for row, text in enumerate(["dejag AA test", "The quick brown", "fox jumps over", "1234567890 !?"]):
        d.text((4, 4 + row * 16), text, fill=(20, 20, 60), font=font)
    sharp = np.asarray(img)
    moved = Image.fromarray(np.roll(sharp, 1, axis=1)).filter(ImageFilter.GaussianBlur(0.7))
    cases["text"] = (sharp, np.asarray(moved))

    # Colour: saturated blobs against a hue-rotated, noisier version.
    blobs = np.zeros((h, w, 3))
    for _ in range(12):
        cy, cx, r = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(5, 20)
        colour = rng.uniform(0, 255, 3)
        mask = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
        blobs[mask] = colour
    rotated = blobs[..., [1, 2, 0]] * 0.3 + blobs * 0.7 + rng.normal(0, 4, blobs.shape)
    cases["colour"] = (to_u8(blobs), to_u8(rotated))

    # Odd size, grey: borders and vector tails.
    odd = rng.uniform(0, 255, (23, 37))
    cases["odd_size"] = (to_u8(odd), to_u8(odd * 0.9 + 10 + rng.normal(0, 6, odd.shape)))

    # 16-bit grey: data range 65535.
    deep = rng.uniform(0, 65535, (40, 52))
    deep_test = np.clip(deep + rng.normal(0, 900, deep.shape), 0, 65535)
    cases["deep16"] = (np.rint(deep).astype(np.uint16), np.rint(deep_test).astype(np.uint16))

    # RGBA: alpha is a channel like any other for the metric.
    rgba = rng.uniform(0, 255, (30, 44, 4))
    cases["rgba"] = (to_u8(rgba), to_u8(rgba + rng.normal(0, 10, rgba.shape)))

    # Identical: MSE 0, PSNR +inf.
    cases["identical"] = (cases["noise"][0], cases["noise"][0].copy())
    return cases


def save(path, array):
    if array.dtype == np.uint16:
        Image.fromarray(array, mode="I;16").save(path)
    else:
        Image.fromarray(array).save(path)


def score(ref, test):
    data_range = 65535 if ref.dtype == np.uint16 else 255
    r = ref.astype(np.float64)
    t = test.astype(np.float64)
    mse = mean_squared_error(r, t)
    psnr = peak_signal_noise_ratio(r, t, data_range=data_range) if mse > 0 else math.inf
    snr = 10 * math.log10(np.mean(r * r) / mse) if mse > 0 else math.inf
    channels = [r] if r.ndim == 2 else [r[..., c] for c in range(r.shape[-1])]
    tests = [t] if t.ndim == 2 else [t[..., c] for c in range(t.shape[-1])]
    per_channel = [structural_similarity(a, b, data_range=data_range, **SSIM_ARGS) for a, b in zip(channels, tests)]
    if r.ndim == 3:
        whole = structural_similarity(r, t, data_range=data_range, channel_axis=-1, **SSIM_ARGS)
    else:
        whole = structural_similarity(r, t, data_range=data_range, **SSIM_ARGS)
    assert abs(whole - np.mean(per_channel)) < 1e-12
    finite = lambda x: x if math.isfinite(x) else "inf"
    return {"data_range": data_range, "mse": mse, "rmse": math.sqrt(mse), "psnr": finite(psnr),
            "snr": finite(snr), "ssim": whole, "ssim_channels": per_channel}


def main():
    os.makedirs(HERE, exist_ok=True)
    rng = np.random.default_rng(20261121)
    expected = {}
    for name, (ref, test) in make_cases(rng).items():
        save(os.path.join(HERE, f"{name}_ref.png"), ref)
        save(os.path.join(HERE, f"{name}_test.png"), test)
        # Score what was written, exactly as the C++ test will read it.
        ref_back = np.asarray(Image.open(os.path.join(HERE, f"{name}_ref.png")))
        test_back = np.asarray(Image.open(os.path.join(HERE, f"{name}_test.png")))
        if ref.dtype == np.uint16:
            ref_back, test_back = ref_back.astype(np.uint16), test_back.astype(np.uint16)
        assert np.array_equal(ref_back, ref) and np.array_equal(test_back, test), name
        expected[name] = score(ref, test)
        print(f"{name:12s} psnr {expected[name]['psnr']!s:>22}  ssim {expected[name]['ssim']:.6f}")

    ref, test = make_cases(np.random.default_rng(20261121))["edges"]
    _, full = structural_similarity(ref.astype(np.float64), test.astype(np.float64), data_range=255, full=True,
                                    **SSIM_ARGS)
    full.astype("<f4").tofile(os.path.join(HERE, "edges_ssim_map.f32"))
    expected["edges"]["ssim_map"] = {"file": "edges_ssim_map.f32", "width": int(ref.shape[1]),
                                     "height": int(ref.shape[0])}
    with open(os.path.join(HERE, "expected.json"), "w") as f:
        json.dump({"generator": "tests/golden/make_metrics_golden.py", "ssim": SSIM_ARGS, "cases": expected}, f,
                  indent=1)


if __name__ == "__main__":
    main()
