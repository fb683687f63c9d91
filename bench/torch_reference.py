"""PyTorch reference for `mrdrive bench policy`: the same networks, the same measurements.

Run on demand, not in CI (needs torch; CPU is enough):
    python bench/torch_reference.py [--threads 2] [--repeats 20] [--train-steps 3] [--quick]

Networks mirror policy/src: ResNet (BasicBlock) with configurable widths, the
global-pooled feature, WoR's action head (feature -> 256 -> 256 -> 6 x 4 x 13,
expanded to 28), the segmentation decoder (3 x ConvTranspose2d stride 2 + BN +
ReLU, 1x1 conv to 6 classes). BN banks do not change the cost (one branch runs),
so one BN per layer is used. Inference: batch 1, eval mode, no_grad, median of
--repeats after 3 warm-up runs. Training: the multi-resolution step (resize to
each scale bilinearly, forward with segmentation, KL action loss + 0.05 CE,
mean over scales, one backward, Adam), batch --batch, samples/s.
"""
import argparse
import statistics
import time

import torch
import torch.nn as nn
import torch.nn.functional as F


class BasicBlock(nn.Module):
    def __init__(self, cin, cout, stride):
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.downsample = None
        if stride != 1 or cin != cout:
            self.downsample = nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))

    def forward(self, x):
        s = x if self.downsample is None else self.downsample(x)
        y = F.relu(self.bn1(self.conv1(x)))
        return F.relu(self.bn2(self.conv2(y)) + s)


class Policy(nn.Module):
    def __init__(self, blocks, widths):
        super().__init__()
        self.conv1 = nn.Conv2d(3, widths[0], 7, 2, 3, bias=False)
        self.bn1 = nn.BatchNorm2d(widths[0])
        self.maxpool = nn.MaxPool2d(3, 2, 1)
        layers, cin = [], widths[0]
        for i, (n, w) in enumerate(zip(blocks, widths)):
            layers.append(nn.Sequential(*[BasicBlock(cin if b == 0 else w, w, 2 if (b == 0 and i > 0) else 1) for b in range(n)]))
            cin = w
        self.layers = nn.Sequential(*layers)
        d = widths[3]
        self.act_head = nn.Sequential(nn.Linear(d, 256), nn.ReLU(True), nn.Linear(256, 256), nn.ReLU(True), nn.Linear(256, 6 * 4 * 13))
        c = [d, d // 2, d // 4, d // 8]
        seg = []
        for i in range(3):
            seg += [nn.ConvTranspose2d(c[i], c[i + 1], 3, 2, 1, 1), nn.BatchNorm2d(c[i + 1]), nn.ReLU(True)]
        seg.append(nn.Conv2d(c[3], 6, 1))
        self.seg_head = nn.Sequential(*seg)

    def forward(self, x, with_seg=False):
        f = self.layers(self.maxpool(F.relu(self.bn1(self.conv1(x)))))
        raw = self.act_head(f.mean(dim=[2, 3])).view(-1, 6, 4, 13)
        steer, throt, brake = raw[..., :9], raw[..., 9:12], raw[..., 12:]
        z = torch.cat([steer.repeat(1, 1, 1, 3) + throt.repeat_interleave(9, -1), brake], -1)
        return z, (self.seg_head(f) if with_seg else None)


def size(h, w, r):
    return int(r * h + 1e-4), int(r * w + 1e-4)


def latency(net, sizes, repeats):
    """Median/min/max ms per input size; sizes interleaved, one run each per round."""
    xs = [torch.randn(1, 3, h, w) for h, w in sizes]
    times = [[] for _ in sizes]
    with torch.no_grad():
        for i in range(3 + repeats):
            for k, x in enumerate(xs):
                t0 = time.perf_counter()
                net(x)
                if i >= 3:
                    times[k].append((time.perf_counter() - t0) * 1e3)
    return [(statistics.median(t), min(t), max(t)) for t in times]


def train_throughput(net, h, w, batch, steps, scales=(0.75, 1.0), seg_weight=0.05):
    net.train()
    for p in net.act_head.parameters():
        p.requires_grad_(False)
    opt = torch.optim.Adam([p for p in net.parameters() if p.requires_grad], lr=1.5e-4)
    x = torch.randn(batch, 3, h, w)
    q = torch.rand(batch, 6, 4, 28) * 0.05
    seg = torch.randint(0, 6, (batch, h, w))
    target = F.softmax(q / 0.01, dim=-1)

    def step():
        losses = []
        for r in scales:
            xr = x if r == 1.0 else F.interpolate(x, size=size(h, w, r), mode="bilinear", align_corners=False)
            z, s = net(xr, with_seg=seg_weight > 0)
            loss = F.kl_div(F.log_softmax(z, -1), target, reduction="none").sum(-1).mean()
            if seg_weight > 0:
                loss = loss + seg_weight * F.cross_entropy(F.interpolate(s, size=(h, w)), seg)
            losses.append(loss)
        loss = sum(losses) / len(losses)
        opt.zero_grad()
        loss.backward()
        opt.step()

    step()
    t0 = time.perf_counter()
    for _ in range(steps):
        step()
    return batch * steps / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--train-steps", type=int, default=3)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    r18, r34 = [2, 2, 2, 2], [3, 4, 6, 3]
    full, half = [64, 128, 256, 512], [32, 64, 128, 256]
    nets = [("default: resnet18 half 32-256", r18, half, 96, 240)]
    if not a.quick:
        nets += [
            ("resnet18 64-512 @ 240x96", r18, full, 96, 240),
            ("resnet18 64-512 @ 480x192", r18, full, 192, 480),
            ("resnet34 64-512 @ 240x96", r34, full, 96, 240),
            ("resnet34 64-512 @ 480x192 (paper)", r34, full, 192, 480),
            ("resnet18 half 32-256 @ 480x192", r18, half, 192, 480),
        ]
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, batch 1 inference, median of {a.repeats} (scales interleaved)")
    print("load average before:", open("/proc/loadavg").read().strip())
    print(f"{'network':<36} {'scale':>6} {'input WxH':>10} {'median ms':>10} {'min ms':>9} {'max ms':>9} {'t(.75)/t(1)':>12}")
    for name, blocks, widths, h, w in nets:
        net = Policy(blocks, widths).eval()
        scales = (0.75, 1.0)
        stats = latency(net, [size(h, w, r) for r in scales], a.repeats)
        med = {r: st[0] for r, st in zip(scales, stats)}
        for i, (r, (m, lo, hi)) in enumerate(zip(scales, stats)):
            hh, ww = size(h, w, r)
            ratio = f"{med[0.75] / med[1.0]:.3f}" if r == 1.0 else ""
            print(f"{name if i == 0 else '':<36} {r:>6} {f'{ww}x{hh}':>10} {m:>10.2f} {lo:>9.2f} {hi:>9.2f} {ratio:>12}")
    if a.train_steps > 0:
        for what, sw in [("segmentation on (weight 0.05)", 0.05), ("segmentation off", 0.0)]:
            sps = train_throughput(Policy(r18, half), 96, 240, a.batch, a.train_steps, seg_weight=sw)
            print(f"training, multi-resolution step (0.75x + 1.0x, {what}, Adam, head frozen), default model, batch {a.batch}: {sps:.1f} samples/s")


if __name__ == "__main__":
    main()
