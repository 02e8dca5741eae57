import itertools

import pytest

from sim.mavlink import Sitl, SitlConfig

_instances = itertools.count(11)


@pytest.fixture
def sitl_factory():
    """Start SITL vehicles on their own instance ports; stop them after the test."""
    started: list[Sitl] = []

    def make(**kw) -> Sitl:
        kw.setdefault("speedup", 6.0)
        s = Sitl(SitlConfig(instance=next(_instances), **kw)).start()
        started.append(s)
        return s

    yield make
    for s in started:
        s.stop()
        assert not s.errors, s.errors[:1]
