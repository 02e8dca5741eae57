"""Policies by name, for the CLI and the evaluation harness. Entries are factories imported
lazily, so listing names does not import torch."""

from __future__ import annotations

from collections.abc import Callable

from sim.gridworld import GridConfig

from ..base import Policy

Factory = Callable[..., Policy]
_REGISTRY: dict[str, tuple[Factory, str]] = {}


def register_policy(name: str, factory: Factory, description: str = "") -> None:
    _REGISTRY[name] = (factory, description)


def known_policies() -> dict[str, str]:
    return {k: d for k, (_, d) in sorted(_REGISTRY.items())}


def make_policy(name: str, cfg: GridConfig | None = None, **kwargs) -> Policy:
    if name not in _REGISTRY:
        raise KeyError(f"unknown policy {name!r}; known: {', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[name][0](cfg=cfg, **kwargs)


def _oracle(cfg=None, **_):
    from ..groundtruth import PlanPolicy

    return PlanPolicy("pt")


def _cu(cfg=None, **_):
    from ..groundtruth import PlanPolicy

    return PlanPolicy("cu")


def _simple(cls_name: str) -> Factory:
    def make(cfg=None, **_):
        from . import simple

        return getattr(simple, cls_name)()

    return make


def _network(default: str) -> Factory:
    def make(cfg=None, checkpoint=None, **kw):
        from ..nn import load_policy, shipped_checkpoint

        return load_policy(checkpoint or shipped_checkpoint(default), cfg=cfg, **kw)

    return make


register_policy("oracle", _oracle, "optimal PT with full knowledge of the targets (upper bound)")
register_policy("cu", _cu, "closest unvisited target, with full knowledge (Eq. 2-3)")
register_policy("ns", _simple("NaivePolicy"), "naive solution: visible target, else vote (paper V-D)")
register_policy("frontier", _simple("FrontierPolicy"), "greedy: nearest unvisited cell")
register_policy("lawnmower", _simple("LawnmowerPolicy"), "boustrophedon sweep from the nearest corner")
register_policy("random", _simple("RandomPolicy"), "uniformly random valid moves")
def _drqn(cfg=None, checkpoint=None, **_):
    from ..drqn import DrqnPolicy
    from ..nn import shipped_checkpoint

    return DrqnPolicy.load(checkpoint or shipped_checkpoint("drqn_static_random"))


register_policy("drqn", _drqn, "DRQN baseline trained by reward (shipped checkpoint or --checkpoint)")
register_policy("dualstream", _network("dualstream_static_random"), "the dual-stream network (shipped checkpoint or --checkpoint)")
register_policy("ssn", _network("ssn_static_random"), "split-stream baseline network (shipped checkpoint or --checkpoint)")
