"""A small campaign for the tests: short trains at low speed, a few milliseconds per run."""
from __future__ import annotations

import socket
from pathlib import Path

SMALL = """\
name: {name}
seed: 11
runs: {runs}
batch_size: {batch}
sampling: {sampling}
manoeuvres:
  - {{kind: emergency, speed_kmh: {{uniform: [{v_lo}, {v_hi}]}}}}
families:
  - name: short
    wagons: [3, 5]
    g_fraction: 0.3
    isolated_fraction: 0.1
    wagon_types:
      Shimmns:
        tare_t: 22.0
        loaded_fraction: 0.7
        payload_t: {{histogram: {{edges: [20.0, 40.0, 58.0], weights: [1.0, 3.0]}}}}
couplers:
  - file: couplers/buffer_hook_pugi.yaml
    draft_strength_kN: 850.0
    buff_strength_kN: 2000.0
uncertainties:
  k0: {{normal: {{mean: 2.7, sd: 0.1}}}}
"""


def write_campaign(folder: Path, name: str = "small", runs: int = 16, batch: int = 2,
                   sampling: str = "monte_carlo", v_lo: float = 30.0, v_hi: float = 50.0) -> Path:
    """Write the small campaign and return its path."""
    path = folder / f"{name}.yaml"
    path.write_text(SMALL.format(name=name, runs=runs, batch=batch, sampling=sampling,
                                 v_lo=v_lo, v_hi=v_hi))
    return path


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
