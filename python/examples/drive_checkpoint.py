"""Drive a shipped mrdrive checkpoint from PyTorch through the Gymnasium environment.

    pip install ./python torch safetensors
    python python/examples/drive_checkpoint.py models/original.safetensors \
        scenarios/paper/town01_route0.toml --scale 1.0 --seed 0

The network is built in PyTorch with torchvision's ResNet names (the names
`mrdrive policy import-torchvision` reads; bench/torch_reference.py's network);
the weights of the checkpoint's BN branch for the scale are copied in. Each step
decodes the logits as mrdrive's policy driver does (dataset/src/decode.rs): the
command's logits interpolated between speed bins at the measured speed, brake if
P(brake) > 0.5, else the expected steer and throttle (at least 0.4, none above
10 km/h on turns and 20 km/h otherwise). At the end it prints the result like
`mrdrive run`; `mrdrive run SCENARIO --checkpoint CKPT --scale S --seed N` drives
the same weights in Rust for comparison.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from safetensors.numpy import load_file

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python"))
sys.path.insert(0, str(ROOT / "bench"))
from mrdrive_gym import MrdriveEnv  # noqa: E402
from torch_reference import BasicBlock  # noqa: E402  (the benchmark's block: the same layers and names)

STEERS = np.linspace(-1.0, 1.0, 9)
THROTTLES = np.array([0.0, 0.5, 1.0])
SPEED_BINS = np.array([1.0, 3.0, 5.0, 7.0])


class Policy(nn.Module):
    """ResNet (torchvision names: conv1, bn1, layer1..4) + WoR's factorised action head."""

    def __init__(self, blocks, widths):
        super().__init__()
        self.conv1 = nn.Conv2d(3, widths[0], 7, 2, 3, bias=False)
        self.bn1 = nn.BatchNorm2d(widths[0])
        cin = widths[0]
        for i, (n, w) in enumerate(zip(blocks, widths)):
            layer = nn.Sequential(*[BasicBlock(cin if b == 0 else w, w, 2 if (b == 0 and i > 0) else 1) for b in range(n)])
            setattr(self, f"layer{i + 1}", layer)
            cin = w
        self.fc1 = nn.Linear(widths[3], 256)
        self.fc2 = nn.Linear(256, 256)
        self.fc3 = nn.Linear(256, 6 * 4 * 13)

    def forward(self, x):
        x = F.max_pool2d(F.relu(self.bn1(self.conv1(x))), 3, 2, 1)
        for i in range(1, 5):
            x = getattr(self, f"layer{i}")(x)
        h = F.relu(self.fc2(F.relu(self.fc1(x.mean(dim=[2, 3])))))
        raw = self.fc3(h).view(-1, 6, 4, 13)
        steer, throttle, brake = raw[..., :9], raw[..., 9:12], raw[..., 12:]
        # Action t * 9 + s has logit steer[s] + throttle[t]; 27 is brake.
        return torch.cat([steer.repeat(1, 1, 1, 3) + throttle.repeat_interleave(9, -1), brake], -1)


def load(checkpoint: Path, scale: float) -> tuple[Policy, dict]:
    config = json.loads(checkpoint.with_suffix(".json").read_text())["config"]
    blocks = {"resnet18": [2, 2, 2, 2], "resnet34": [3, 4, 6, 3]}[config["depth"]]
    net = Policy(blocks, config["widths"]).eval()
    branch = config["scales"].index(scale)
    ours = load_file(str(checkpoint))
    state = {}
    for k, v in ours.items():
        if k.startswith("seg_head."):
            continue  # training only
        if ".branches." in k and f".branches.{branch}." not in k:
            continue  # another scale's BN
        name = k.removeprefix("backbone.").removeprefix("action_head.")
        name = name.replace("downsample.conv.", "downsample.0.").replace("downsample.bn.", "downsample.1.")
        name = name.replace(f".branches.{branch}.gamma", ".weight").replace(f".branches.{branch}.beta", ".bias")
        name = name.replace(f".branches.{branch}.", ".")
        t = torch.from_numpy(v.copy())
        if name.startswith("fc") and name.endswith(".weight"):
            t = t.T.contiguous()  # burn stores Linear weights as [in, out]
        state[name] = t
    missing, unexpected = net.load_state_dict(state, strict=False)
    missing = [m for m in missing if not m.endswith("num_batches_tracked")]
    if missing or unexpected:
        raise SystemExit(f"{checkpoint}: names do not match: missing {missing}, unexpected {unexpected}")
    return net, config


def decode(logits: np.ndarray, speed: float, command: int) -> np.ndarray:
    """mrdrive's decoding (dataset/src/decode.rs) of logits [6, 4, 28]."""
    z = logits[command]
    if speed <= SPEED_BINS[0]:
        l = z[0]
    elif speed >= SPEED_BINS[-1]:
        l = z[-1]
    else:
        b = int(np.searchsorted(SPEED_BINS, speed, side="right")) - 1
        w = (speed - SPEED_BINS[b]) / (SPEED_BINS[b + 1] - SPEED_BINS[b])
        l = (1 - w) * z[b] + w * z[b + 1]
    p = np.exp(l - l.max())
    p /= p.sum()
    if p[27] > 0.5:
        return np.array([0.0, 0.0, 1.0], np.float32)
    drive = p[:27] / p[:27].sum()
    steer = float((drive * np.tile(STEERS, 3)).sum())
    throttle = float((drive * np.repeat(THROTTLES, 9)).sum())
    limit = 10 / 3.6 if command in (0, 1) else 20 / 3.6
    throttle = 0.0 if speed > limit else max(throttle, 0.4)
    return np.array([steer, throttle, 0.0], np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("scenario")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--vehicles", type=int)
    ap.add_argument("--pedestrians", type=int)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    net, config = load(a.checkpoint, a.scale)
    mean = np.array(config["mean"], np.float32)
    std = np.array(config["std"], np.float32)
    env = MrdriveEnv(a.scenario, scale=a.scale, vehicles=a.vehicles, pedestrians=a.pedestrians)
    obs, _ = env.reset(seed=a.seed)
    with torch.no_grad():
        while True:
            x = (obs["image"].astype(np.float32) / 255.0 - mean) / std
            logits = net(torch.from_numpy(x.transpose(2, 0, 1)[None].copy()))[0].numpy()
            control = decode(logits, float(obs["speed"][0]), int(obs["command"]))
            obs, _, term, trunc, info = env.step(control)
            if term or trunc:
                break
    env.close()
    r = info["record"]["result"]
    print(f"scenario      {r['provenance']['scenario']}  seed {r['settings']['seed']}  scale {a.scale}")
    print(f"result        {'SUCCESS' if r['success'] else 'FAILURE'}  completion {r['completion_pct']:.1f} % "
          f"of {r['route_length_m']:.0f} m  driving score {r['driving_score']:.1f}")
    print(f"ended by      {r['termination'] or 'route completed'}")
    print("infractions")
    for kind, n in r["counts"].items():
        print(f"  {kind:<22} {n}")


if __name__ == "__main__":
    main()
