#!/usr/bin/python3
"""Golden fixtures for dejag's nn layers, losses and optimizers, computed by PyTorch.

Run with Debian's interpreter (`make golden`, or /usr/bin/python3 tests/golden/make_nn_golden.py); it needs
python3-torch. For every layer configuration it writes tests/golden/nn/<case>.safetensors holding:
  inputs and parameters as F32 (the exact values both sides use), and
  the forward output and every gradient as F64, computed by PyTorch in float64 from those F32 values,
with the configuration as JSON in the metadata key "config". The C++ tests (tests/nn/golden_test.cpp)
run dejag's float32 kernels and require forward relative error <= 1e-5 and backward <= 1e-4 (max abs
difference over max abs reference value).
"""
import os
import sys

import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import golden_io  # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "nn")
torch.manual_seed(20261121)


def write_safetensors(path, tensors, config):
    golden_io.write_safetensors(path, {name: t.detach().contiguous().numpy() for name, t in tensors.items()},
                                config)


def f32(*shape, low=-1.0, high=1.0):
    return (torch.rand(*shape, dtype=torch.float32) * (high - low) + low)


def run(fn, inputs, params):
    """Forward in float64 from the float32 values, backward with a random upstream gradient."""
    leaves = {k: v.double().requires_grad_(True) for k, v in {**inputs, **params}.items()}
    out = fn(**leaves)
    dout = f32(*out.shape)
    out.backward(dout.double())
    result = {k: v for k, v in {**inputs, **params}.items()}
    result["dout"] = dout
    result["output"] = out.detach()
    for k, v in leaves.items():
        result["d" + k] = v.grad.detach()
    return result


cases = {}


def conv2d_case(name, n, cin, cout, h, w, k, stride=1, pad=(0, 0, 0, 0), dilation=1, bias=True):
    kh, kw = (k, k) if isinstance(k, int) else k
    inputs = {"input": f32(n, cin, h, w)}
    params = {"weight": f32(cout, cin, kh, kw, low=-0.5, high=0.5)}
    if bias:
        params["bias"] = f32(cout)
    top, bottom, left, right = pad

    def fn(input, weight, bias=None):
        return F.conv2d(F.pad(input, (left, right, top, bottom)), weight, bias, stride=stride, dilation=dilation)

    cases[name] = (run(fn, inputs, params), {"layer": "conv2d", "batch": n, "in_channels": cin, "out_channels": cout,
                   "height": h, "width": w, "kernel": [kh, kw], "stride": stride, "pad": list(pad),
                   "dilation": dilation, "bias": bias})


def conv_transpose_case(name, n, cin, cout, h, w, k, stride, pad, output_padding, dilation=1, bias=True):
    inputs = {"input": f32(n, cin, h, w)}
    params = {"weight": f32(cin, cout, k, k, low=-0.5, high=0.5)}
    if bias:
        params["bias"] = f32(cout)

    def fn(input, weight, bias=None):
        return F.conv_transpose2d(input, weight, bias, stride=stride, padding=pad, output_padding=output_padding,
                                  dilation=dilation)

    cases[name] = (run(fn, inputs, params), {"layer": "conv_transpose2d", "batch": n, "in_channels": cin,
                   "out_channels": cout, "height": h, "width": w, "kernel": k, "stride": stride, "pad": pad,
                   "output_padding": output_padding, "dilation": dilation, "bias": bias})


def maxpool_case(name, n, c, h, w, k, stride, pad, ties=False):
    x = f32(n, c, h, w)
    if ties:
        x = torch.round(x * 2) / 2  # few distinct values: ties everywhere
    cases[name] = (run(lambda input: F.max_pool2d(input, k, stride, pad), {"input": x}, {}),
                   {"layer": "maxpool2d", "batch": n, "channels": c, "height": h, "width": w, "kernel": k,
                    "stride": stride, "pad": pad})


def activation_case(name, kind, fn, scale=3.0, **extra):
    x = f32(2, 3, 7, 9, low=-scale, high=scale)
    cases[name] = (run(lambda input: fn(input), {"input": x}, {}), {"layer": "activation", "kind": kind,
                   "shape": list(x.shape), **extra})


def resample_case(name, kind, factor, n, c, h, w):
    x = f32(n, c, h, w)
    if kind == "nearest":
        fn = lambda input: F.interpolate(input, scale_factor=factor, mode="nearest")
    elif kind == "bilinear":
        fn = lambda input: F.interpolate(input, scale_factor=factor, mode="bilinear", align_corners=False)
    else:
        fn = lambda input: F.pixel_shuffle(input, factor)
    cases[name] = (run(fn, {"input": x}, {}), {"layer": kind, "factor": factor, "batch": n, "channels": c,
                   "height": h, "width": w})


def kernel_filter_case(name, n, c, h, w, k, centre_bias, logit_scale=2.0, history=False):
    """dejag's kernel_filter: a softmax-weighted average of each pixel's k x k neighbourhood, edges repeated;
    with a history, one more weight (the last logit) takes the history's own pixel."""
    count = k * k + (1 if history else 0)
    inputs = {"input": f32(n, c, h, w), "logits": f32(n, count, h, w, low=-logit_scale, high=logit_scale)}
    if history:
        inputs["history"] = f32(n, c, h, w)

    def fn(input, logits, history=None):
        bias = torch.zeros(count, dtype=logits.dtype)
        bias[k * k // 2] = centre_bias
        weights = torch.softmax(logits + bias.view(1, count, 1, 1), dim=1)  # (N, k^2 (+1), H, W)
        r = k // 2
        padded = F.pad(input, (r, r, r, r), mode="replicate")
        taps = F.unfold(padded, k).view(n, c, k * k, h, w)  # tap j = (dy + r) k + (dx + r)
        if history is not None:
            taps = torch.cat([taps, history.unsqueeze(2)], dim=2)
        return (taps * weights.unsqueeze(1)).sum(dim=2)

    config = {"layer": "kernel_filter", "batch": n, "channels": c, "height": h, "width": w, "kernel": k,
              "centre_bias": centre_bias}
    if history:
        config["history"] = True
    cases[name] = (run(fn, inputs, {}), config)


def accumulate_case(name, n, c, h, w, k, max_count, confidence_high=1.0, clip=False):
    """dejag's accumulate: the frame's k x k neighbourhood by the softmax of k^2 logits, blended with the
    history's colour by a = m / (1 + m), m = min(1, 2 sigmoid(last logit)) n, n = s / (1 - s) from the history's last
    channel s (clamped to [0, N / (N + 1)]); the history is blended the same way with the pixel's own
    sample (the kept colour); the means in linear light (the history's colour is linear, the frame's
    sRGB-encoded: decoded, and the shown colour encoded); the output is the shown colour, the kept colour
    and n' / (n' + 1), n' = min(1 + m, N). With clip, the history's colour is first clamped to
    [decode(min), decode(max)] of the k x k taps (history colours drawn wider, so that both bounds bite)."""
    inputs = {"input": f32(n, c, h, w, low=0.0, high=1.0),
              "logits": f32(n, k * k + 1, h, w, low=-2.0, high=2.0),
              "history": torch.cat([f32(n, c, h, w, low=-0.3 if clip else 0.0, high=1.3 if clip else 1.0),
                                    f32(n, 1, h, w, low=0.0, high=confidence_high)], dim=1)}

    def fn(input, logits, history):
        weights = torch.softmax(logits[:, :k * k], dim=1)
        r = k // 2
        padded = F.pad(input, (r, r, r, r), mode="replicate")
        taps = F.unfold(padded, k).view(n, c, k * k, h, w)
        spatial = (taps * weights.unsqueeze(1)).sum(dim=2)
        s = history[:, c:].clamp(0.0, max_count / (max_count + 1.0))
        m = torch.clamp(2 * torch.sigmoid(logits[:, k * k:]), max=1.0) * s / (1 - s)
        a = m / (1 + m)
        def decode(v):
            v = v.clamp(0.0, 1.0)
            return torch.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)

        def encode(x):
            x = x.clamp(0.0, 1.0)
            return torch.where(x <= 0.0031308, x * 12.92, 1.055 * x.clamp(min=1e-12) ** (1 / 2.4) - 0.055)

        filtered, own = decode(spatial), decode(input)
        colour = history[:, :c]
        if clip:
            colour = torch.maximum(torch.minimum(colour, decode(taps.max(dim=2).values)),
                                   decode(taps.min(dim=2).values))
        shown = encode(filtered + a * (colour - filtered))
        kept = own + a * (colour - own)
        count = torch.clamp(1 + m, max=max_count)
        return torch.cat([shown, kept, count / (count + 1)], dim=1)

    config = {"layer": "accumulate", "batch": n, "channels": c, "height": h, "width": w, "kernel": k,
              "max_count": max_count}
    if clip:
        config["clip"] = True
    cases[name] = (run(fn, inputs, {}), config)


def warp_case(name, n, c, h, w, mode, reach):
    """dejag's warp: each pixel reads the image at (x - motion_x, y - motion_y) in pixel indices, edge
    pixels repeated: grid_sample with align_corners=False and border padding (bicubic: a = -0.75)."""
    inputs = {"input": f32(n, c, h, w), "motion": f32(n, 2, h, w, low=-reach, high=reach)}

    def fn(input, motion):
        ys, xs = torch.meshgrid(torch.arange(h, dtype=motion.dtype), torch.arange(w, dtype=motion.dtype),
                                indexing="ij")
        sx, sy = xs - motion[:, 0], ys - motion[:, 1]
        grid = torch.stack([(2 * sx + 1) / w - 1, (2 * sy + 1) / h - 1], dim=-1)
        return F.grid_sample(input, grid, mode=mode, padding_mode="border", align_corners=False)

    cases[name] = (run(fn, inputs, {}), {"layer": "warp", "batch": n, "channels": c, "height": h, "width": w,
                                         "filter": mode})


def gaussian_window():
    coords = torch.arange(11, dtype=torch.float64) - 5
    g = torch.exp(-0.5 * coords ** 2 / 1.5 ** 2)
    g = g / g.sum()
    return torch.outer(g, g)


def ssim_loss(pred, target, data_range=1.0):
    c = pred.shape[1]
    win = gaussian_window().to(pred.dtype).expand(c, 1, 11, 11)
    f = lambda x: F.conv2d(x, win, groups=c)
    mx, my = f(target), f(pred)
    vx = f(target * target) - mx * mx
    vy = f(pred * pred) - my * my
    cxy = f(target * pred) - mx * my
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return 1 - s.mean()


def loss_case(name, kind, pred, target, data_range=1.0):
    p = pred.double().requires_grad_(True)
    t = target.double()
    if kind == "ssim":
        loss = ssim_loss(p, t, data_range)
    elif kind == "l1":
        loss = F.l1_loss(p, t)
    else:
        loss = F.mse_loss(p, t)
    loss.backward()
    cases[name] = ({"pred": pred, "target": target, "loss": loss.detach().reshape(1), "dpred": p.grad},
                   {"layer": "loss", "kind": kind, "shape": list(pred.shape), "data_range": data_range})


def optimizer_case(name, kind, steps=5, **kw):
    params = f32(257)
    grads = [f32(257) for _ in range(steps)]
    lrs = [1e-2 * (1 + 0.1 * i) for i in range(steps)]
    p = params.clone().requires_grad_(True)
    opt = {"sgd": torch.optim.SGD, "adam": torch.optim.Adam, "adamw": torch.optim.AdamW}[kind]([p], lr=lrs[0], **kw)
    tensors = {"params": params}
    for i in range(steps):
        for group in opt.param_groups:
            group["lr"] = lrs[i]
        p.grad = grads[i].clone()
        opt.step()
        tensors[f"grad{i}"] = grads[i]
        tensors[f"after{i}"] = p.detach().clone().double()
    cases[name] = (tensors, {"layer": "optimizer", "kind": kind, "steps": steps, "lrs": lrs, **kw})


class Seed2020(torch.nn.Module):
    """docs/seed-cnn.md as dejag builds it (nn/model.cpp builtinArchitecture("seed2020"))."""

    def __init__(self):
        super().__init__()
        nn = torch.nn
        self.conv1 = nn.Conv2d(1, 32, 5, padding=2)
        self.conv2 = nn.Conv2d(32, 32, 3, padding=1)
        self.conv3 = nn.Conv2d(32, 64, 1)
        self.conv4 = nn.Conv2d(64, 128, 3, padding=1)
        self.up1 = nn.ConvTranspose2d(128, 64, 3, stride=2, padding=1, output_padding=1)
        self.up2 = nn.ConvTranspose2d(64, 1, 3, stride=2, padding=1, output_padding=1)

    def forward(self, x):
        x = F.relu(self.conv2(F.relu(self.conv1(x))))
        x = F.relu(self.conv3(F.max_pool2d(x, 2)))
        x = F.relu(self.conv4(F.max_pool2d(x, 2)))
        return torch.sigmoid(self.up2(F.relu(self.up1(x))))


def seed2020_adam_case(steps=5, lr=1e-3):
    """5 Adam steps of seed2020 on one fixed batch with the 1 - SSIM loss: loss per step, final weights."""
    model = Seed2020().double()
    initial = {}
    for name, p in model.named_parameters():
        value = f32(*p.shape, low=-0.15, high=0.15) if name.endswith("weight") else f32(*p.shape, low=-0.05, high=0.05)
        initial[name] = value
        with torch.no_grad():
            p.copy_(value.double())
    target = f32(2, 1, 16, 16, low=0.0, high=1.0)
    inputs = (target + f32(2, 1, 16, 16, low=-0.15, high=0.15)).clamp(0, 1)
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    losses, first_gradients = [], {}
    for step in range(steps):
        opt.zero_grad()
        loss = ssim_loss(model(inputs.double()), target.double())
        loss.backward()
        if step == 0:  # the whole graph's backward, before Adam touches anything
            first_gradients = {n: p.grad.detach().clone().float() for n, p in model.named_parameters()}
        opt.step()
        losses.append(loss.item())
    tensors = {"input": inputs, "target": target, "losses": torch.tensor(losses, dtype=torch.float64)}
    for name, value in first_gradients.items():
        tensors["grad0." + name] = value
    for name, value in initial.items():
        tensors["initial." + name] = value
    for name, p in model.named_parameters():
        tensors["final." + name] = p.detach().clone().float()  # F32 keeps the fixture small
    cases["seed2020_adam5"] = (tensors, {"layer": "seed2020_training", "steps": steps, "lr": lr, "loss": "ssim"})


def main():
    os.makedirs(HERE, exist_ok=True)
    # Conv2D: kernel sizes 1, 3, 5; strides; same/valid/explicit/asymmetric padding; dilation; bias or not.
    conv2d_case("conv2d_k3_same", 2, 3, 5, 9, 11, 3, pad=(1, 1, 1, 1))
    conv2d_case("conv2d_k5_same_seed_layer1", 1, 1, 4, 13, 10, 5, pad=(2, 2, 2, 2))
    conv2d_case("conv2d_k1_nobias", 2, 4, 6, 5, 7, 1, bias=False)
    conv2d_case("conv2d_k3_stride2", 2, 2, 3, 10, 13, 3, stride=2, pad=(1, 1, 1, 1))
    conv2d_case("conv2d_k3_dilation2", 1, 3, 2, 12, 9, 3, pad=(2, 2, 2, 2), dilation=2)
    conv2d_case("conv2d_k3_valid", 2, 3, 4, 8, 6, 3)
    conv2d_case("conv2d_k3_stride2_keras_same", 1, 3, 3, 8, 10, 3, stride=2, pad=(0, 1, 0, 1))
    conv2d_case("conv2d_k2x4_asymmetric", 1, 2, 3, 7, 9, (2, 4), pad=(1, 0, 2, 1))
    # ConvTranspose2D: stride 2 with padding/output_padding, stride 1, dilation, no bias.
    conv_transpose_case("convt_k3_s2_p1_op1_seed", 2, 4, 3, 5, 6, 3, 2, 1, 1)
    conv_transpose_case("convt_k3_s2_p0", 1, 3, 2, 4, 5, 3, 2, 0, 0)
    conv_transpose_case("convt_k2_s2", 2, 2, 3, 3, 4, 2, 2, 0, 0, bias=False)
    conv_transpose_case("convt_k3_s1_p1", 1, 3, 4, 6, 5, 3, 1, 1, 0)
    conv_transpose_case("convt_k3_s2_dilation2", 1, 2, 2, 4, 4, 3, 2, 2, 1, dilation=2)
    conv_transpose_case("convt_k4_s3_p1_op2", 1, 2, 3, 3, 5, 4, 3, 1, 2)
    # MaxPool2D.
    maxpool_case("maxpool_k2_s2_odd", 2, 3, 9, 11, 2, 2, 0)
    maxpool_case("maxpool_k3_s2_p1", 1, 2, 8, 7, 3, 2, 1)
    maxpool_case("maxpool_k2_s1", 1, 2, 5, 6, 2, 1, 0)
    maxpool_case("maxpool_k2_s2_ties", 2, 2, 6, 8, 2, 2, 0, ties=True)
    # Activations.
    activation_case("act_relu", "relu", F.relu)
    activation_case("act_leaky_relu", "leaky_relu", lambda x: F.leaky_relu(x, 0.1), slope=0.1)
    activation_case("act_sigmoid", "sigmoid", torch.sigmoid, scale=40.0)
    activation_case("act_clamp", "clamp", lambda x: torch.clamp(x, 0.0, 1.0), low=0.0, high=1.0)
    # Resampling.
    resample_case("up_nearest_x2", "nearest", 2, 2, 3, 5, 7)
    resample_case("up_bilinear_x2", "bilinear", 2, 2, 2, 5, 6)
    resample_case("up_bilinear_x3", "bilinear", 3, 1, 2, 4, 5)
    resample_case("pixel_shuffle_x2", "pixel_shuffle", 2, 2, 8, 4, 5)
    # Losses.
    target = f32(2, 3, 16, 19, low=0.0, high=1.0)
    pred = (target + f32(2, 3, 16, 19, low=-0.2, high=0.2)).clamp(0, 1)
    loss_case("loss_ssim", "ssim", pred, target)
    loss_case("loss_ssim_flat_target", "ssim", f32(1, 1, 14, 15, low=0.4, high=0.6), torch.full((1, 1, 14, 15), 0.5))
    loss_case("loss_ssim_hdr", "ssim", f32(1, 2, 12, 13, low=0.0, high=50.0), f32(1, 2, 12, 13, low=0.0, high=50.0),
              data_range=50.0)
    loss_case("loss_l1", "l1", pred, target)
    loss_case("loss_mse", "mse", pred, target)
    # Optimizers, 5 steps with changing learning rates.
    optimizer_case("optim_sgd_momentum", "sgd", momentum=0.9)
    optimizer_case("optim_sgd_momentum_wd", "sgd", momentum=0.8, weight_decay=0.01)
    optimizer_case("optim_adam", "adam", betas=(0.9, 0.999), eps=1e-8)
    optimizer_case("optim_adam_wd", "adam", weight_decay=0.05)
    optimizer_case("optim_adamw", "adamw", weight_decay=0.1)
    # The whole graph: 5 Adam steps of seed2020.
    seed2020_adam_case()
    # The kernel filter (kpn's output): 3x3 raised centre, 5x5 on an image smaller than the kernel, 1x1,
    # and logits large enough that a naive softmax would overflow.
    kernel_filter_case("kernel_filter_k3_centre4", 2, 3, 6, 7, 3, 4.0)
    kernel_filter_case("kernel_filter_k5_small_image", 1, 2, 3, 4, 5, 0.0)
    kernel_filter_case("kernel_filter_k1", 1, 3, 4, 5, 1, 0.0)
    kernel_filter_case("kernel_filter_k3_large_logits", 1, 3, 5, 6, 3, -2.5, logit_scale=60.0)

    # The motion warp: reads inside the image and across its borders (motion up to 3 pixels on 7x9).
    warp_case("warp_bilinear", 2, 3, 7, 9, "bilinear", 3.0)
    warp_case("warp_bicubic", 2, 3, 7, 9, "bicubic", 3.0)
    warp_case("warp_bicubic_small_image", 1, 2, 3, 2, "bicubic", 1.5)
    # The kernel filter with a history tap (the temporal network's blend of frame and history).
    kernel_filter_case("kernel_filter_k3_history", 2, 3, 6, 7, 3, 0.0, history=True)
    kernel_filter_case("kernel_filter_k1_history_large_logits", 1, 2, 4, 5, 1, 1.0, logit_scale=60.0,
                       history=True)
    # The accumulate blend (the accumulate family's output): uncapped, and with a cap of 3 samples that
    # confidences up to 0.95 reach and pass.
    accumulate_case("accumulate_k3", 2, 3, 6, 7, 3, 1000.0, confidence_high=0.97)
    accumulate_case("accumulate_k1_capped", 1, 2, 5, 4, 1, 3.0, confidence_high=0.95)
    # With the history clamped to the neighbourhood's range.
    accumulate_case("accumulate_k3_clip", 2, 3, 6, 7, 3, 1000.0, confidence_high=0.97, clip=True)

    for name, (tensors, config) in cases.items():
        write_safetensors(os.path.join(HERE, name + ".safetensors"), tensors, config)
    print(f"wrote {len(cases)} fixtures to {HERE}")


if __name__ == "__main__":
    main()
