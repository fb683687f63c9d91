"""The client side of `mrdrive serve` (see sim/src/remote/server.rs for the protocol).

A frame is a little-endian u32 length, that much JSON, a little-endian u64 length,
that many payload bytes. Images arrive as the payload and become a NumPy array
with one `frombuffer` call: no per-pixel Python work.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path
from typing import Any

import numpy as np


class ServerError(RuntimeError):
    """The server refused a request (the message says what was wrong) or died."""


def find_binary(explicit: str | os.PathLike | None = None) -> str:
    """The `mrdrive` executable: `explicit`, $MRDRIVE_BIN, the repository's
    target/release/mrdrive (when this package is used from <repo>/python, or the working
    folder is the repository), or `mrdrive` on PATH."""
    candidates = [explicit, os.environ.get("MRDRIVE_BIN")]
    repo = Path(__file__).resolve().parents[2]
    candidates.append(repo / "target" / "release" / "mrdrive")
    candidates.append(Path.cwd() / "target" / "release" / "mrdrive")
    for c in candidates:
        if c and Path(c).is_file() and os.access(c, os.X_OK):
            return str(c)
    on_path = shutil.which("mrdrive")
    if on_path:
        return on_path
    raise ServerError(
        "cannot find the mrdrive binary; fix: run `cargo build --release` in the repository, "
        "set MRDRIVE_BIN, or pass binary=... to the environment"
    )


class Server:
    """One `mrdrive serve` process, spoken to over its stdin and stdout."""

    def __init__(self, binary: str | os.PathLike | None = None, cwd: str | os.PathLike | None = None):
        self.binary = find_binary(binary)
        self.proc = subprocess.Popen(
            [self.binary, "serve"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=None,  # the server's warnings reach the user's terminal
            cwd=cwd,
            bufsize=0,
        )

    def request(self, message: dict[str, Any]) -> tuple[dict[str, Any], bytes]:
        """Sends one request and returns the answer and its payload; raises
        ServerError with the server's message if it refused."""
        if self.proc.poll() is not None:
            raise ServerError(f"the mrdrive server has exited (code {self.proc.returncode})")
        text = json.dumps(message).encode()
        frame = struct.pack("<I", len(text)) + text + struct.pack("<Q", 0)
        try:
            self.proc.stdin.write(frame)
            self.proc.stdin.flush()
            n = struct.unpack("<I", self._read(4))[0]
            answer = json.loads(self._read(n))
            m = struct.unpack("<Q", self._read(8))[0]
            payload = self._read(m) if m else b""
        except (BrokenPipeError, EOFError, struct.error) as e:
            code = self.proc.poll()
            raise ServerError(f"the mrdrive server died (exit code {code}): {e}") from None
        if not answer.get("ok", False):
            raise ServerError(answer.get("error", "the server refused the request"))
        return answer, payload

    def _read(self, n: int) -> bytes:
        chunks, got = [], 0
        while got < n:
            b = self.proc.stdout.read(n - got)
            if not b:
                raise EOFError("end of the server's output")
            chunks.append(b)
            got += len(b)
        return b"".join(chunks)

    def close(self) -> None:
        """Ends the server (politely, then by force); safe to call twice."""
        if self.proc.poll() is None:
            try:
                self.request({"op": "close"})
            except ServerError:
                pass
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


def image_of(obs: dict[str, Any] | None, payload: bytes) -> np.ndarray:
    """The RGB8 image of an answer, H x W x 3 (a view of the payload's bytes)."""
    if not obs or not payload:
        return np.zeros((0, 0, 3), np.uint8)
    h, w = obs["height"], obs["width"]
    return np.frombuffer(payload, np.uint8, count=h * w * 3).reshape(h, w, 3)


def classes_of(obs: dict[str, Any] | None, payload: bytes) -> np.ndarray:
    """The class image of an answer (WoR's ids 0-5), H x W, when it holds one."""
    if not obs or not obs.get("classes"):
        return np.zeros((0, 0), np.uint8)
    h, w = obs["height"], obs["width"]
    return np.frombuffer(payload, np.uint8, count=h * w, offset=h * w * 3).reshape(h, w)
