"""Writes tiny torchvision-style ResNet-18 state dicts as safetensors, with numpy only.

Usage: python write_torchvision_tiny.py OUT_DIR

The network is torchvision's resnet18 layout with widths 4-8-8-16 (stem 4).
Every float tensor named NAME with n elements holds, at flat index i,
    ((i * 7 + len(NAME)) % 13) / 13 - 0.5     (+ 1.0 for running_var)
so the Rust test can check every value it loads. Files written:
  tiny_resnet18.safetensors   complete, with num_batches_tracked and fc.*
  tiny_prefixed.safetensors   the same keys under "backbone_wide." plus a foreign head
  tiny_missing.safetensors    without layer4.1.conv2.weight
  tiny_badshape.safetensors   layer3.0.conv1.weight with a wrong shape
"""
import sys
from pathlib import Path

import numpy as np
from safetensors.numpy import save_file

WIDTHS = [4, 8, 8, 16]
BLOCKS = [2, 2, 2, 2]


def value(name, shape):
    n = int(np.prod(shape))
    v = ((np.arange(n) * 7 + len(name)) % 13) / 13.0 - 0.5
    if name.endswith("running_var"):
        v = v + 1.0
    return v.astype(np.float32).reshape(shape)


def bn(sd, name, c):
    for p in ["weight", "bias", "running_mean", "running_var"]:
        sd[f"{name}.{p}"] = value(f"{name}.{p}", (c,))
    sd[f"{name}.num_batches_tracked"] = np.array(7, dtype=np.int64)


def state_dict():
    sd = {}
    sd["conv1.weight"] = value("conv1.weight", (WIDTHS[0], 3, 7, 7))
    bn(sd, "bn1", WIDTHS[0])
    cin = WIDTHS[0]
    for s, (w, nb) in enumerate(zip(WIDTHS, BLOCKS)):
        for b in range(nb):
            p = f"layer{s + 1}.{b}"
            stride = 2 if (b == 0 and s > 0) else 1
            sd[f"{p}.conv1.weight"] = value(f"{p}.conv1.weight", (w, cin, 3, 3))
            bn(sd, f"{p}.bn1", w)
            sd[f"{p}.conv2.weight"] = value(f"{p}.conv2.weight", (w, w, 3, 3))
            bn(sd, f"{p}.bn2", w)
            if stride != 1 or cin != w:
                sd[f"{p}.downsample.0.weight"] = value(f"{p}.downsample.0.weight", (w, cin, 1, 1))
                bn(sd, f"{p}.downsample.1", w)
            cin = w
    sd["fc.weight"] = value("fc.weight", (10, WIDTHS[3]))
    sd["fc.bias"] = value("fc.bias", (10,))
    return sd


def main():
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    sd = state_dict()
    save_file(sd, str(out / "tiny_resnet18.safetensors"))
    pre = {f"backbone_wide.{k}": v for k, v in sd.items()}
    pre["act_head.0.weight"] = np.zeros((3, 3), dtype=np.float32)
    save_file(pre, str(out / "tiny_prefixed.safetensors"))
    missing = dict(sd)
    del missing["layer4.1.conv2.weight"]
    save_file(missing, str(out / "tiny_missing.safetensors"))
    bad = dict(sd)
    bad["layer3.0.conv1.weight"] = np.zeros((8, 4, 3, 3), dtype=np.float32)
    save_file(bad, str(out / "tiny_badshape.safetensors"))


if __name__ == "__main__":
    main()
