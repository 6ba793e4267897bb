"""Route each strip frame to the network whose prior it calls for, decided by a classifier on the readings.

No single strip network has kept both priors it was taught: the shape library's (spheres, blocks, rings,
edges: where the paper's rule leaves ghosts) and the generic one of fields from no named object (random
shapes, product fields: where the rule is close to right). The readings tell the two kinds of frame apart
(docs/strips.md, "Information or learning?"), so a model card may name a second network and a router:
a frame the router calls *generic* is answered by that network, every other frame by the card's own
(:class:`~tactile_learn.runtime.OnnxEstimator` does the routing; the two networks take the same
readings and give the same outputs).

The router is a small MLP in numpy (two hidden ReLU layers) on the readings' loads above the readout's
offset as shares of their total, and the log of the total: a frame's shape, then its load. Its weights
ship in an ``.npz`` file whose SHA-256 the card holds. A frame with a NaN or an infinite reading gets a
NaN logit, which is not generic: it goes to the card's own network, whose input check refuses it with
the usual error.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ModelError
from synth.io import sha256_file

__all__ = ["PriorRoute", "ReadingsMlp", "load_router_arrays", "route_features"]

#: the arrays a router file holds, with their dimensions (``f``: the features, the readings and their total's
#: log; ``h``: hidden width; ``c``: outputs, one logit for this router, one per class for
#: :class:`~tactile_learn.known_objects.ObjectRouter`)
_ARRAYS = {
    "mean": ("f",),
    "std": ("f",),
    "w0": ("h", "f"),
    "b0": ("h",),
    "w1": ("h", "h"),
    "b1": ("h",),
    "w2": ("c", "h"),
    "b2": ("c",),
}
_FLOAT32 = np.dtype(np.float32)


def route_features(readings: np.ndarray, offset: float, share_scale: float) -> np.ndarray:
    """The router's features, unfolded (:class:`PriorRoute` folds them into its first layer): (B, n + 1)
    float32, each reading's load above ``offset`` as a share of the frame's total, times
    ``share_scale``, then the log of the total (floored at 1e-4: a frame at rest)."""
    above = np.clip(readings - np.float32(offset), np.float32(0.0), None)
    total = above.sum(axis=1, keepdims=True)
    share = above / np.maximum(total, np.float32(1e-6))
    return np.concatenate([share * np.float32(share_scale), np.log(np.maximum(total, np.float32(1e-4)))], axis=1)


class ReadingsMlp:
    """A router's network in numpy: the readings' features (:func:`route_features`) through two hidden ReLU
    layers to ``c`` logits, its first layer folded with the features' normalisation."""

    def __init__(self, arrays: dict[str, np.ndarray], offset: float, share_scale: float) -> None:
        if not (math.isfinite(offset) and math.isfinite(share_scale) and share_scale > 0.0):
            raise ModelError(f"router offset {offset!r} and share scale {share_scale!r} must be finite (scale > 0)")
        self.offset, self.share_scale = float(offset), float(share_scale)
        a = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
        n = a["mean"].shape[0] - 1  # readings per frame
        # The first layer folded with the features' normalisation: for loads above the offset ``u``
        # (total ``T``), features ``x = (u S / T, log T)``, ``W0 ((x - mean) / std) + b0`` is
        # ``(S / T) A u + c log T + b`` with ``A = W0[:, :n] / std[:n]``, ``c = W0[:, n] / std[n]``,
        # ``b = b0 - W0 (mean / std)``: one product with the loads and two scalars a frame (folded in
        # float64, run in float32; the tests hold it to the unfolded arithmetic)
        w0 = a["w0"] / a["std"]
        self.load_weights = np.ascontiguousarray(w0[:, :n].T, dtype=np.float32)  # (n, hidden)
        self.log_weights = w0[:, n].astype(np.float32)
        self.bias0 = (a["b0"] - w0 @ a["mean"]).astype(np.float32)
        self.w1t, self.b1 = np.ascontiguousarray(a["w1"].T, dtype=np.float32), a["b1"].astype(np.float32)
        self.w2t, self.b2s = np.ascontiguousarray(a["w2"].T, dtype=np.float32), a["b2"].astype(np.float32)
        self._offset32 = np.float32(self.offset)

    def hidden(self, readings: np.ndarray) -> np.ndarray:
        """(B, h) float32: the second hidden layer's activations for readings (B, n) (NaN rows for frames
        with a NaN or infinite reading)."""
        with np.errstate(invalid="ignore", over="ignore"):
            above = np.maximum(readings - self._offset32, np.float32(0.0))
            total = above.sum(axis=1, keepdims=True)
            scale = np.float32(self.share_scale) / np.maximum(total, np.float32(1e-6))
            log_total = np.log(np.maximum(total, np.float32(1e-4)))
            h = np.maximum((above @ self.load_weights) * scale + log_total * self.log_weights + self.bias0, 0.0)
            return np.maximum(h @ self.w1t + self.b1, np.float32(0.0))

    def logits(self, readings: np.ndarray) -> np.ndarray:
        """(B, c) float32 logits for readings (B, n)."""
        with np.errstate(invalid="ignore", over="ignore"):
            return self.hidden(readings) @ self.w2t + self.b2s


def load_router_arrays(path: Path, sha256: str, inputs: int, outputs: int) -> dict[str, np.ndarray]:
    """The arrays of the router file ``path`` (an ``.npz`` of :data:`_ARRAYS`), checked against its card's
    ``sha256``, the model's ``inputs`` (readings per frame) and the router's ``outputs`` (logits)."""
    if not path.is_file():
        raise ModelError(f"{path}: router file not found (the model card routes frames through it)")
    if sha256_file(path) != sha256:
        raise ModelError(f"{path}: checksum differs from its card's: the router is corrupt or belongs to another card")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.asarray(data[k]) for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise ModelError(f"{path}: cannot read the router ({exc})") from None
    missing = sorted(set(_ARRAYS) - set(arrays))
    if missing:
        raise ModelError(f"{path}: the router lacks {', '.join(missing)}")
    sizes = {"f": inputs + 1, "h": arrays["b0"].shape[0] if arrays["b0"].ndim == 1 else -1, "c": outputs}
    for name, dims in _ARRAYS.items():
        want = tuple(sizes[d] for d in dims)
        if arrays[name].shape != want:
            raise ModelError(f"{path}: router array {name} has shape {arrays[name].shape}, expected {want}")
        if not np.isfinite(arrays[name]).all():
            raise ModelError(f"{path}: router array {name} holds NaN or infinite values")
    if not (arrays["std"] > 0).all():
        raise ModelError(f"{path}: router array std must be positive")
    return arrays


class PriorRoute(ReadingsMlp):
    """The router of a routed model card: :meth:`generic` of a batch, :meth:`generic_frame` of one frame."""

    def __init__(self, arrays: dict[str, np.ndarray], offset: float, share_scale: float, threshold: float) -> None:
        if not 0.0 < threshold < 1.0:
            raise ModelError(f"router threshold {threshold!r} is not a probability strictly between 0 and 1")
        super().__init__(arrays, offset, share_scale)
        self.threshold = float(threshold)
        #: the logit at or above which a frame is generic (``threshold`` as a probability)
        self.logit_threshold = math.log(threshold / (1.0 - threshold))
        self.w2, self.b2 = self.w2t[:, 0], float(self.b2s[0])

    @classmethod
    def load(
        cls, path: Path, sha256: str, inputs: int, offset: float, share_scale: float, threshold: float
    ) -> PriorRoute:
        """The router in ``path`` (an ``.npz`` of :data:`_ARRAYS` with one output), checked against its card's
        ``sha256`` and the model's ``inputs`` (readings per frame)."""
        return cls(load_router_arrays(path, sha256, inputs, 1), offset, share_scale, threshold)

    def logit(self, readings: np.ndarray) -> np.ndarray:
        """(B,) the router's logit of generic for readings (B, n) (NaN for a frame with a NaN or
        infinite reading)."""
        with np.errstate(invalid="ignore", over="ignore"):
            return self.hidden(readings) @ self.w2 + np.float32(self.b2)

    def generic(self, readings: np.ndarray) -> np.ndarray:
        """(B,) bool: the frames the router sends to the generic network (NaN logits: not generic)."""
        return np.asarray(self.logit(readings) >= self.logit_threshold)

    def generic_frame(self, frame: np.ndarray) -> bool:
        """:meth:`generic` of one frame (1, n), as a Python bool: the same arithmetic with the
        frame's scalars as Python floats (fewer numpy calls: ~a third of the batch path's time)."""
        above = np.maximum(frame[0] - self._offset32, np.float32(0.0))
        total = float(above.sum())
        if not total < math.inf:  # a NaN or infinite reading: not generic (the input check refuses it)
            return False
        scale = self.share_scale / (total if total > 1e-6 else 1e-6)
        log_total = math.log(total if total > 1e-4 else 1e-4)
        h = above @ self.load_weights
        h *= scale
        h += self.log_weights * log_total + self.bias0
        np.maximum(h, 0.0, out=h)
        h = h @ self.w1t
        h += self.b1
        np.maximum(h, 0.0, out=h)
        return float(h @ self.w2) + self.b2 >= self.logit_threshold

    @staticmethod
    def save(path: Path, arrays: dict[str, Any]) -> None:
        """Write a router file (the arrays of :data:`_ARRAYS`, float32)."""
        with Path(path).open("wb") as handle:  # (a file object: numpy adds no ".npz" to the name)
            np.savez(handle, allow_pickle=False, **{k: np.asarray(arrays[k], dtype=np.float32) for k in _ARRAYS})
