"""Reads a dataset written by mrdrive with NumPy and safetensors, the way
docs/dataset.md shows, and prints what it found as JSON for the Rust test to
check. Usage: read_dataset.py DIR"""

import json
import sys

import numpy as np
import zstandard
from safetensors import safe_open
from safetensors.numpy import load_file


def decode_images(shard, views, h, w):
    """Each frame's images are zstd-compressed on their own: RGB then classes."""
    blob, offsets = shard["images"], shard["offsets"]
    n = len(offsets) - 1
    rgb = np.empty((n, views, h, w, 3), np.uint8)
    classes = np.empty((n, views, h, w), np.uint8)
    d = zstandard.ZstdDecompressor()
    for i in range(n):
        raw = np.frombuffer(d.decompress(blob[offsets[i]:offsets[i + 1]].tobytes()), np.uint8)
        rgb[i] = raw[: views * h * w * 3].reshape(views, h, w, 3)
        classes[i] = raw[views * h * w * 3:].reshape(views, h, w)
    return rgb, classes


root = sys.argv[1]
index = json.load(open(f"{root}/dataset.json"))
ep = index["episodes"][1]
shard = load_file(f"{root}/{ep['shard']}")
labels = load_file(f"{root}/{ep['labels']}")
(w, h), views = index["s0"], len(index["view_yaws_deg"])
rgb, classes = decode_images(shard, views, h, w)
x, y, yaw, speed = shard["ego"].T
q, valid = labels["q"], labels["valid"].astype(bool)

# The docs' example: the first labelled frame, its command, the nearest speed bin.
i, view = int(np.flatnonzero(valid)[0]), 0
cmd = int(shard["command"][i])
b = int(np.argmin(np.abs(np.array([1, 3, 5, 7]) - speed[i])))
values = q[i, view, cmd, b]
target = np.exp((values - values.max()) / 0.01)
target /= target.sum()

with safe_open(f"{root}/{ep['labels']}", framework="numpy") as f:
    label_meta = f.metadata()
with safe_open(f"{root}/{ep['shard']}", framework="numpy") as f:
    shard_meta = f.metadata()

out = {
    "name": index["name"],
    "s0": index["s0"],
    "views": index["view_yaws_deg"],
    "episodes": len(index["episodes"]),
    "shapes": {k: list(v.shape) for k, v in {**shard, "rgb": rgb, "classes": classes, **labels}.items()},
    "dtypes": {k: str(v.dtype) for k, v in {**shard, "rgb": rgb, "classes": classes, **labels}.items()},
    "rgb_2_1_3_5": rgb[2, 1, 3, 5].tolist(),
    "classes_2_1_0_5": int(classes[2, 1, 0, 5]),
    "ego_3": shard["ego"][3].tolist(),
    "command": shard["command"].tolist(),
    "route_3": shard["route"][3].tolist(),
    "tick": shard["tick"].tolist(),
    "actors_3": shard["actors"][3].tolist(),
    "lights_2": shard["lights"][2].tolist(),
    "q_2_1_3_2": q[2, 1, 3, 2].tolist(),
    "valid": valid.tolist(),
    "example": {"frame": i, "command": cmd, "bin": b, "best": int(values.argmax()),
                "p_best": float(target.max())},
    "label_meta": label_meta,
    "shard_format": shard_meta["format"],
}
print(json.dumps(out))
