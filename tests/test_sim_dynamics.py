"""The simulator's full vehicle model: physics against closed forms, sensors against the truth motion."""

from __future__ import annotations

import hashlib

from autosar_cli.config import load_config
from autosar_cli.sim.simulate import SimulationResult

# sha256 of the ci scenario, seed 7, MCAP, simulated by the code at 687f0ab (before the full model existed).
CI_SEED7_MCAP_SHA256 = "419f0a87bcc79944b793394784702d5687e834212cc0897a55cefac1e709cf4d"


def test_kinematic_drive_is_byte_identical_to_before(ci_mcap: SimulationResult) -> None:
    assert load_config().simulation.dynamics == "kinematic"
    digest = hashlib.sha256(ci_mcap.log_path.read_bytes()).hexdigest()
    assert digest == CI_SEED7_MCAP_SHA256
