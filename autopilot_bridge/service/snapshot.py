"""An object's state as plain data: a JSON tree plus named arrays (for an npz), and back.

Why not pickle: a journal is read back into a vehicle's companion, and unpickling a file runs
whatever it says; JSON and an npz loaded with allow_pickle=False run nothing. Why generic: the
policy's own state (a belief's maps, a planner's tour, a DRQN's hidden state, a loop guard's
queue, every random stream) differs from policy to policy, and a list kept by hand per policy
is the list someone forgets to extend. So every attribute is taken, recursively, except what
`reset()` rebuilds the same from the configuration and never changes afterwards:

- frozen dataclasses (configs), torch modules (the trained network), functions;
- the attribute names a class lists in `journal_skip` (caches whose content is rebuilt
  lazily, e.g. a fast inference path holding a copy of its network's weights).

Restoring overlays the saved attributes onto an object that `reset()` has just built, so what
was skipped stays as reset made it. Floats go into JSON by repr (exact); arrays keep dtype
and shape; two attributes holding the same array (or object) are restored as one.
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any

import numpy as np

#: JSON keys marking non-JSON values in a tree
_ARRAY, _RNG, _TUPLE, _ALIAS, _OBJ, _SCALAR, _TENSOR, _ITEMS = (
    "__array__", "__rng__", "__tuple__", "__alias__", "__object__", "__scalar__", "__tensor__", "__items__")


class SnapshotError(ValueError):
    """A state that cannot be written as plain data, or a tree that does not fit the object."""


def _skipped(value: Any) -> bool:
    """Rebuilt by reset() from the configuration: not search state."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type) and value.__dataclass_params__.frozen:
        return True
    if callable(value) and not hasattr(value, "__dict__"):
        return True
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(value, torch.nn.Module | torch.device | torch.dtype):
        return True  # the trained network (from its checkpoint), where it runs
    return isinstance(value, type) or type(value).__name__ in ("function", "builtin_function_or_method", "method")


def _is_tensor(value: Any) -> bool:
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(value, torch.Tensor)


class Encoder:
    """Encodes objects into one tree and one dict of arrays (shared ids give aliases)."""

    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray] = {}
        self._ids: dict[int, str] = {}
        self._keep: list[Any] = []  # keeps encoded objects alive, so their ids stay unique

    def encode(self, value: Any, path: str) -> Any:
        if value is None or isinstance(value, bool | int | float | str):
            return value
        if isinstance(value, np.generic):
            return {_SCALAR: value.dtype.str, "value": value.item()}
        if id(value) in self._ids:  # arrays, lists, dicts and objects met before: the same one
            return {_ALIAS: self._ids[id(value)]}
        if isinstance(value, np.ndarray):
            if value.dtype == object:
                raise SnapshotError(f"{path}: an object array cannot be written without pickle")
            self._remember(value, path)
            self.arrays[path] = np.ascontiguousarray(value)
            return {_ARRAY: path}
        if _is_tensor(value):
            self.arrays[path] = value.detach().cpu().numpy().copy()
            return {_TENSOR: path, "dtype": str(value.dtype)}
        if isinstance(value, np.random.Generator):
            return {_RNG: value.bit_generator.state}
        if isinstance(value, tuple):
            return {_TUPLE: [self.encode(v, f"{path}.{i}") for i, v in enumerate(value)]}
        if isinstance(value, list):
            self._remember(value, path)
            return [self.encode(v, f"{path}.{i}") for i, v in enumerate(value)]
        if isinstance(value, dict):
            self._remember(value, path)
            if all(isinstance(k, str) and not k.startswith("__") for k in value):
                return {k: self.encode(v, f"{path}.{k}") for k, v in value.items()}
            # keys that are not plain strings (a count per cell): as a list of pairs
            return {_ITEMS: [[self.encode(k, f"{path}.k{i}"), self.encode(v, f"{path}.{i}")]
                             for i, (k, v) in enumerate(value.items())]}
        if hasattr(value, "__dict__"):
            self._remember(value, path)
            return {_OBJ: type(value).__qualname__, "attrs": self.attrs(value, path)}
        raise SnapshotError(f"{path}: a {type(value).__name__} cannot be written as plain data")

    def attrs(self, obj: Any, path: str) -> dict[str, Any]:
        """The object's attributes as a tree, those reset() rebuilds left out."""
        skip = set(getattr(type(obj), "journal_skip", ()))
        return {k: self.encode(v, f"{path}.{k}") for k, v in vars(obj).items()
                if k not in skip and not _skipped(v)}

    def _remember(self, value: Any, path: str) -> None:
        self._ids[id(value)] = path
        self._keep.append(value)


class Decoder:
    """Decodes a tree from `Encoder` against its arrays, restoring aliases."""

    def __init__(self, arrays: Any) -> None:
        self.arrays = arrays
        self._paths: dict[str, Any] = {}

    def decode(self, node: Any, current: Any, path: str) -> Any:
        """The value for `node`; `current` is what the object holds now (reset's), whose type
        a random stream or a nested object is restored into."""
        if not isinstance(node, dict | list):
            return node
        if isinstance(node, list):
            out = [self.decode(v, None, f"{path}.{i}") for i, v in enumerate(node)]
            self._paths[path] = out
            return out
        if _ALIAS in node:
            try:
                return self._paths[node[_ALIAS]]
            except KeyError:
                raise SnapshotError(f"{path}: refers to {node[_ALIAS]}, which is not restored before it") from None
        if _SCALAR in node:
            return np.dtype(node[_SCALAR]).type(node["value"])
        if _ARRAY in node:
            a = self._array(node[_ARRAY], path)
            self._paths[path] = a
            return a
        if _TENSOR in node:
            import torch

            return torch.from_numpy(self._array(node[_TENSOR], path).copy())
        if _RNG in node:
            rng = current if isinstance(current, np.random.Generator) else None
            if rng is None or type(rng.bit_generator).__name__ != node[_RNG].get("bit_generator"):
                bitgen = getattr(np.random, node[_RNG]["bit_generator"])
                rng = np.random.Generator(bitgen())
            rng.bit_generator.state = node[_RNG]
            return rng
        if _TUPLE in node:
            cur = current if isinstance(current, tuple) and len(current) == len(node[_TUPLE]) else (None,) * len(node[_TUPLE])
            return tuple(self.decode(v, c, f"{path}.{i}") for i, (v, c) in enumerate(zip(node[_TUPLE], cur, strict=True)))
        if _OBJ in node:
            if current is None or type(current).__qualname__ != node[_OBJ]:
                raise SnapshotError(f"{path}: the journal holds a {node[_OBJ]}, the policy here a "
                                    f"{type(current).__qualname__}: not the same policy")
            self._paths[path] = current
            self.restore_attrs(current, node["attrs"], path)
            return current
        out: dict[Any, Any] = {}
        self._paths[path] = out
        if _ITEMS in node:
            for i, (k, v) in enumerate(node[_ITEMS]):
                out[self.decode(k, None, f"{path}.k{i}")] = self.decode(v, None, f"{path}.{i}")
        else:
            out.update({k: self.decode(v, None, f"{path}.{k}") for k, v in node.items()})
        return out

    def restore_attrs(self, obj: Any, attrs: dict[str, Any], path: str) -> None:
        for k, node in attrs.items():
            setattr(obj, k, self.decode(node, getattr(obj, k, None), f"{path}.{k}"))

    def _array(self, key: str, path: str) -> np.ndarray:
        try:
            return np.array(self.arrays[key])
        except KeyError:
            raise SnapshotError(f"{path}: array {key!r} is missing from the journal's arrays") from None


def snapshot(obj: Any, name: str, enc: Encoder | None = None) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(tree, arrays) of obj's attributes; arrays are named under `name`."""
    enc = enc or Encoder()
    return enc.attrs(obj, name), enc.arrays


def restore(obj: Any, tree: dict[str, Any], arrays: Any, name: str) -> None:
    """Overlay a `snapshot` onto obj (just reset, so what the snapshot skipped is reset's)."""
    Decoder(arrays).restore_attrs(obj, tree, name)
