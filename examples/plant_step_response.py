"""Drive the exact plant directly: apply voltage vector 4 (phase a high) to the niu2020 IPMSM held at
1500 rpm by the dyno and print the phase currents and torque of the first periods.

Run: python examples/plant_step_response.py [--periods N]
"""

from __future__ import annotations

import argparse

from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor


def main(periods: int) -> list[float]:
    """Print one line per period; returns the torque samples [N·m]."""
    params = load_motor("niu2020-ipmsm")
    plant = Plant(params, 100e-6, DynoMechanics(1500.0))
    torques = []
    for _ in range(periods):
        plant.advance([4], [100_000])  # state code 4·Sa + 2·Sb + Sc = 100 for the whole period
        s = plant.sample()
        torques.append(s.torque)
        print(f"t = {s.t * 1e3:6.2f} ms  i_abc = ({s.i_a:+6.3f}, {s.i_b:+6.3f}, {s.i_c:+6.3f}) A  "
              f"torque = {s.torque:+6.3f} N·m  ({plant.last_trace.shape[0]} trace rows)")
    return torques


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--periods", type=int, default=10)
    main(parser.parse_args().periods)
