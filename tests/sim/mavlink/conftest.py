import itertools

import pytest
from udp_ports import free_udp_port

from sim.mavlink import Sitl, SitlConfig

_instances = itertools.count(11)
PORTS = ("api_local_port", "api_remote_port", "gcs_local_port", "gcs_remote_port")




@pytest.fixture
def sitl_factory():
    """Start SITL vehicles on ports of their own; stop them after the test."""
    started: list[Sitl] = []

    def make(**kw) -> Sitl:
        kw.setdefault("speedup", 6.0)
        kw.setdefault("instance", next(_instances) % 40)
        taken = {kw[n] for n in PORTS if n in kw}
        for name in PORTS:
            while name not in kw:  # four different ports: the OS may hand a just-freed one out twice
                port = free_udp_port()
                if port not in taken:
                    kw[name] = port
                    taken.add(port)
        s = Sitl(SitlConfig(**kw)).start()
        started.append(s)
        return s

    yield make
    for s in started:
        s.stop()
        assert not s.errors, s.errors[:1]
        assert not s.vehicle.counters.handler_errors, s.vehicle.counters.handler_errors[:3]


@pytest.fixture
def lossy_sitl(sitl_factory):
    """A SITL vehicle whose API link runs through a seeded FaultProxy: returns (sitl, proxy,
    port the client listens on)."""
    from sim.mavlink.faultproxy import FaultProxy

    proxies: list[FaultProxy] = []

    def make(up, down=None, seed: int = 0, **kw):
        vehicle_port, client_port = free_udp_port(), free_udp_port()
        proxy = FaultProxy(vehicle_port, client_port, up, down, seed=seed).start()
        proxies.append(proxy)
        sitl = sitl_factory(api_local_port=vehicle_port, api_remote_port=proxy.vehicle_side_port, **kw)
        return sitl, proxy, client_port

    yield make
    for p in proxies:
        p.stop()
