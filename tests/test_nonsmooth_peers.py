"""MuJoCo's soft contacts against the analytic references of the contact problems
(benchmarks/nonsmooth_peers.py): every tolerance follows from the stated softness
(solref = (tau, zeta), constant impedance d, timestep h), so a wrong reference or a wrongly
built MuJoCo model (drop height, restitution, friction, masses) fails."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="MuJoCo is in the bench extra")

from benchmarks.nonsmooth_peers import (  # noqa: E402
    SOFTNESS,
    analytic,
    mujoco_motion,
    quantities,
)
from workbench.problems.ch5_contacts import (  # noqa: E402
    BALL_DROP,
    BALL_RESTITUTION,
    GRAVITY,
    INCLINE,
    SPHERE_RADIUS,
    SPHERE_SPEED,
)

H, TAU, D = SOFTNESS.timestep, SOFTNESS.timeconst, SOFTNESS.impedance


def test_soft_ball_rebounds_as_its_spring_damper():
    """solref's damping ratio zeta = -ln e / sqrt(pi^2 + ln^2 e) rebounds with e (to 1 %:
    the pulling force clamped at separation adds 0.7 %); the impact lasts pi tau zeta /
    sqrt(1 - zeta^2) and sinks v1 tau zeta exp(-zeta phi / sqrt(1 - zeta^2)),
    phi = atan(sqrt(1 - zeta^2) / zeta)."""
    motion = mujoco_motion("bouncing-ball", 2.0)
    measured, expected = quantities("bouncing-ball", motion), analytic("bouncing-ball")
    zeta = SOFTNESS.dampratio(BALL_RESTITUTION)
    assert measured["impact_1_s"] == pytest.approx(expected["impact_1_s"], abs=2 * H)
    restitution = math.sqrt(measured["apex_1_m"] / BALL_DROP)
    assert restitution == pytest.approx(BALL_RESTITUTION, rel=1e-2)
    v1 = GRAVITY * expected["impact_1_s"]
    root = math.sqrt(1 - zeta**2)
    duration = math.pi * TAU * zeta / root
    second = measured["impact_1_s"] + duration + 2 * restitution * v1 / GRAVITY
    assert measured["impact_2_s"] == pytest.approx(second, abs=0.1 * duration)
    depth = v1 * TAU * zeta * math.exp(-zeta * math.atan(root / zeta) / root)
    assert measured["penetration_max_m"] == pytest.approx(depth, rel=2e-2)


def test_soft_sphere_sinks_slides_and_rolls_at_five_sevenths():
    """At rest it sinks (1 - d) g tau^2 (zeta = 1); sliding friction is mu N (its cone's
    edge), so it rolls at 5/7 v0; the friction leaves the edge within tau of t_r (soft
    friction damps the last of the slip over about tau / 2); then it rolls without slip
    but that of its radius shortened by the penetration."""
    motion = mujoco_motion("sliding-sphere", 1.0)
    measured, expected = quantities("sliding-sphere", motion), analytic("sliding-sphere")
    np.testing.assert_allclose(-motion.z[-100:], SOFTNESS.rest_penetration(GRAVITY, 0.0),
                               rtol=1e-3)  # fmt: skip
    assert measured["roll_speed_m_s"] == pytest.approx(5 / 7 * SPHERE_SPEED, rel=1e-4)
    assert expected["roll_time_s"] - TAU < measured["roll_time_s"] < expected["roll_time_s"]
    # then it rolls: no slip but that of its rolling radius, shortened by the penetration
    sink = SOFTNESS.rest_penetration(GRAVITY, 0.0)
    spin = 5 / 7 * SPHERE_SPEED / SPHERE_RADIUS
    rolling = motion.times > expected["roll_time_s"] + 5 * TAU
    assert np.all(np.abs(motion.slip[rolling]) < spin * sink)


def test_soft_block_slides_at_coulombs_rate_and_creeps_where_it_sticks():
    """Sliding: s'' = g (sin a - mu cos a) to 1e-4. Stopping: the friction leaves its cone
    within tau before t_s, then the block creeps slower than a single soft contact's
    (1 - d) a_t tau / 2 (four corners share the load)."""
    slide = quantities("incline-block-slide", mujoco_motion("incline-block-slide", 2.0))
    rate = analytic("incline-block-slide")["slide_accel_m_s2"]
    assert slide["slide_accel_m_s2"] == pytest.approx(rate, rel=1e-4)
    stop = quantities("incline-block-stop", mujoco_motion("incline-block-stop", 2.0))
    t_s = analytic("incline-block-stop")["stick_time_s"]
    assert t_s - TAU < stop["stick_time_s"] < t_s
    bound = SOFTNESS.creep_speed(GRAVITY * math.sin(INCLINE))
    assert 0 < stop["creep_speed_m_s"] < bound
    assert stop["s_end_m"] == pytest.approx(analytic("incline-block-stop")["s_end_m"],
                                            abs=bound * 1.0)  # fmt: skip
    assert D < 1
