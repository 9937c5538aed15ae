"""The independent vessel's model (tools/independent_vessel.py) against closed forms.

Its numbers come from VESSEL.md, not from hil, so they are checked here against the
same page: the inertia matrix, a skew-symmetric C, the thrust of each thruster, the
command rate limit, the pod slew, and the steady surge speed under full forward thrust.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tests.tools.tool_loader import load_tool

PATH = Path(__file__).resolve().parents[2] / "tools" / "independent_vessel.py"


@pytest.fixture(scope="module")
def iv() -> ModuleType:
    return load_tool("independent_vessel")


def test_it_imports_nothing_of_hil() -> None:
    source = PATH.read_text()
    assert "import hil" not in source
    assert "from hil" not in source


def test_the_inertia_is_vessel_md_s(iv: ModuleType) -> None:
    np.testing.assert_allclose(iv.M, [[16.11, 0, 0], [0, 24.11, 0.5291], [0, 0.5291, 2.76]],
                               atol=1e-4)


def test_coriolis_does_no_work(iv: ModuleType) -> None:
    for nu in np.random.default_rng(0).uniform(-0.3, 0.3, (20, 3)):
        assert nu @ iv.coriolis(nu) @ nu == pytest.approx(0.0, abs=1e-12)


def test_the_thrusters_push_where_vessel_md_says(iv: ModuleType) -> None:
    # Tunnel, saturated at 0.7, to starboard at x = 0.3875 m.
    tunnel = iv.Actuators(tunnel=0.7)
    np.testing.assert_allclose(iv.thrust(tunnel, 0.0),
                               [0.0, 2.629 * 0.7, 0.3875 * 2.629 * 0.7], atol=1e-12)
    # Port azimuth pushing forward at y = -0.055: a yaw moment of -ly Fx = +0.055 Fx.
    port = iv.Actuators(port=(1.0, 0.0))
    np.testing.assert_allclose(iv.thrust(port, 0.0), [1.03, 0.0, 0.055 * 1.03], atol=1e-12)
    # Starboard azimuth pushing to starboard at x = -0.4574: lx Fy.
    stbd = iv.Actuators(starboard=(0.0, 1.0))
    np.testing.assert_allclose(iv.thrust(stbd, 0.0), [0.0, 1.03, -0.4574 * 1.03], atol=1e-12)


def test_commands_saturate_and_ramp_at_two_per_second(iv: ModuleType) -> None:
    act = iv.Actuators()
    for _ in range(10):  # 0.1 s
        act = iv.actuators_step(act, 1.0, (3.0, 4.0), (0.0, -1.0), 0.01, 0.0)
    assert act.tunnel == pytest.approx(0.2)
    assert act.port == pytest.approx((0.2, 0.2))  # toward (0.6, 0.8), the unit vector
    assert act.starboard == pytest.approx((0.0, -0.2))
    for _ in range(100):
        act = iv.actuators_step(act, 1.0, (3.0, 4.0), (0.0, -1.0), 0.01, 0.0)
    assert act.tunnel == pytest.approx(0.7)
    assert act.port == pytest.approx((0.6, 0.8))


def test_a_slewing_pod_turns_the_short_way_and_pushes_along_its_axis(iv: ModuleType) -> None:
    rate = math.radians(180.0)
    act = iv.Actuators(port=(1.0, 0.0), port_rad=math.pi / 2)  # pod across, asked forward
    act = iv.actuators_step(act, 0.0, (1.0, 0.0), (0.0, 0.0), 0.1, rate)
    assert act.port_rad == pytest.approx(math.pi / 2 - math.radians(18.0))
    along = math.cos(act.port_rad)
    tau = iv.thrust(act, rate)
    assert tau[0] == pytest.approx(1.03 * along * math.cos(act.port_rad))
    # Asked backward from forward: the propeller reverses, the pod stays.
    act = iv.Actuators(port=(-1.0, 0.0), port_rad=0.0)
    assert iv.actuators_step(act, 0.0, (-1.0, 0.0), (0.0, 0.0), 0.1, rate).port_rad == 0.0
    assert iv.thrust(act, rate)[0] == pytest.approx(-1.03)


def test_full_forward_thrust_settles_at_the_damping_root(iv: ModuleType) -> None:
    # Both azimuths forward: X = 2.06 N against d11(u) u = 0.6555 u - 0.3545 u^2 + 3.787 u^3.
    roots = np.roots([3.787, -0.3545, 0.6555, -2.06])
    u_ss = float(roots[np.isreal(roots)].real[0])
    act = iv.Actuators(port=(1.0, 0.0), starboard=(1.0, 0.0))
    tau = iv.thrust(act, 0.0)
    np.testing.assert_allclose(iv.nu_dot(np.array([u_ss, 0.0, 0.0]), tau), 0.0, atol=1e-12)
    x = np.zeros(6)
    for _ in range(60):  # 60 s in 1-s spans: the step size is RK45's business
        x = iv.advance(x, tau, tau, 1.0)
    assert x[3] == pytest.approx(u_ss, abs=1e-4)
    assert abs(x[1]) < 1e-9
    assert abs(x[2]) < 1e-9
