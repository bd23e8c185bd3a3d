"""Working-precision arithmetic on Python floats (firmware_model.precision) against numpy's own float32 and
float64 operations, and the strapdown's fast path (Python floats) against the reference (numpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model.attitude import a2mat, mat2q
from firmware_model.precision import rounder
from firmware_model.strapdown import NavState, strapdown_step, strapdown_step_fast
from protocols.constants import DEG


def test_rounded_double_operations_are_bit_identical_to_numpy_float32():
    rng = np.random.default_rng(7)
    a = (rng.normal(size=20000) * 10.0 ** rng.integers(-12, 4, 20000)).astype(np.float32)
    b = (rng.normal(size=20000) * 10.0 ** rng.integers(-12, 4, 20000)).astype(np.float32)
    r = rounder(np.float32, 6)
    al, bl = a.tolist(), b.tolist()
    got = np.array([r.unpack(r.pack(x * y, x - y, x + y, x / y, 0.5 * x, math.sqrt(abs(x)))) for x, y in zip(al, bl)],
                   dtype=np.float32)
    want = np.stack([a * b, a - b, a + b, a / b, np.float32(0.5) * a, np.sqrt(np.abs(a))], axis=1)
    assert got.tobytes() == want.tobytes()


def test_rounding_to_float32_changes_values_and_float64_is_the_identity():
    r32, r64 = rounder(np.float32, 2), rounder(np.float64, 2)
    assert r32.unpack(r32.pack(0.1, 1 / 3)) == (float(np.float32(0.1)), float(np.float32(1 / 3)))
    assert r32.unpack(r32.pack(0.1, 1 / 3)) != (0.1, 1 / 3)
    assert r64.unpack(r64.pack(0.1, 1 / 3)) == (0.1, 1 / 3)
    with pytest.raises(ValueError):
        rounder(np.float16, 1)


def _state() -> NavState:
    cbn = a2mat(2 * DEG, -3 * DEG, 0.5)
    return NavState(q=mat2q(cbn), v=np.array([3.0, -2.0, 0.1]), pos=np.array([0.7, 2.0, 50.0]),
                    a_prev=np.array([0.01, -0.02, 0.003]))


def test_python_float_strapdown_matches_the_numpy_formulation_to_rounding():
    """The float64 step on Python floats against the same equations in numpy float64 (which use BLAS with FMA
    for the dot and matrix-vector products, so they may differ in the last bits, never more)."""
    from firmware_model import earth
    from firmware_model.attitude import cross3, q2mat, qmul, qnormalize, rv2q

    rng = np.random.default_rng(3)
    T = 0.005
    a, b = _state(), _state()
    for _ in range(2000):
        phi = rng.normal(0.0, 1e-3, 3).astype(np.float32)
        dv = (rng.normal(0.0, 1e-3, 3) + np.array([0.0, 0.0, 9.8 * T])).astype(np.float32)
        strapdown_step_fast(a, phi.tolist(), dv.tolist(), T, np.float64)
        # reference: the numpy formulation, written out (the pre-D-10.F1 implementation)
        lat, lon, h = b.pos
        vh = b.v + b.a_prev * (T / 2)
        rm, rn = earth.radii(lat)
        lat_h = lat + vh[1] / (rm + h) * (T / 2)
        h_h = h + vh[2] * (T / 2)
        sl, cl = math.sin(lat_h), math.cos(lat_h)
        rm, rn = earth.radii(lat_h)
        rmh, rnh = rm + h_h, rn + h_h
        wen = np.array([-vh[1] / rmh, vh[0] / rnh, vh[0] * sl / cl / rnh])
        wie = earth.OMEGA_IE * np.array([0.0, cl, sl])
        w_in, w_cor = wie + wen, 2 * wie + wen
        f_n = q2mat(b.q) @ (dv.astype(np.float64) / T)
        a_n = f_n - cross3(w_in * (T / 2), f_n) - cross3(w_cor, b.v)
        a_n[2] -= earth.gravity(lat_h, h_h)
        v1 = b.v + a_n * T
        vm = 0.5 * (b.v + v1)
        pos = np.array([lat + vm[1] / rmh * T, lon + vm[0] / (rnh * cl) * T, h + vm[2] * T])
        q = qnormalize(qmul(rv2q(-w_in * T), qmul(b.q, rv2q(phi.astype(np.float64)))))
        b = NavState(q, v1, pos, b.t + T, a_n, f_n)
    assert np.allclose(a.q, b.q, rtol=0, atol=1e-14)
    assert np.allclose(a.v, b.v, rtol=0, atol=1e-11)
    assert np.allclose(a.pos[:2], b.pos[:2], rtol=0, atol=1e-15) and abs(a.pos[2] - b.pos[2]) < 1e-9
    assert abs(a.pos[2] - 50.0) > 0.1 and np.abs(a.q - _state().q).max() > 1e-3  # the state moved (not a no-op)


def test_strapdown_step_fast_f64_takes_python_floats_and_arrays_alike():
    a, b = _state(), _state()
    phi, dv = [1e-4, -2e-4, 3e-5], [1e-3, 2e-3, 0.049]
    strapdown_step_fast(a, phi, dv, 0.005, np.float64)
    strapdown_step(b, np.array(phi), np.array(dv), 0.005, dtype=np.float64)
    for x, y in ((a.q, b.q), (a.v, b.v), (a.pos, b.pos), (a.f_n, b.f_n), (a.a_prev, b.a_prev)):
        assert x.tobytes() == y.tobytes()


def test_float32_strapdown_is_bit_identical_to_the_numpy_float32_formulation():
    """strapdown_step_fast in float32 (Python floats rounded by struct, numpy for the dot / matrix products)
    against the reference (numpy) on the same float32 state, step by step."""
    import firmware_model.strapdown as sd

    rng = np.random.default_rng(11)
    T = 0.005

    def state() -> NavState:
        s = _state()
        return NavState(s.q.astype(np.float32), s.v.astype(np.float32), s.pos.copy(), 0.0,
                        s.a_prev.astype(np.float32))

    a, b = state(), state()
    for k in range(500):
        phi = rng.normal(0.0, 1e-3 if k % 2 else 1e-9, 3).astype(np.float32)  # also the rv2q series branch
        dv = (rng.normal(0.0, 1e-3, 3) + np.array([0.0, 0.0, 9.8 * T])).astype(np.float32)
        sd.strapdown_step_fast(a, phi.tolist(), dv.tolist(), T, np.float32)
        sd.strapdown_step(b, phi, dv, T, dtype=np.float32)
        for x, y in ((a.q, b.q), (a.v, b.v), (a.pos, b.pos), (a.f_n, b.f_n), (a.a_prev, b.a_prev)):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), k
    assert abs(a.pos[2] - 50.0) > 0.01  # the state moved


def test_navstate_float_form_builds_read_only_arrays_and_assignment_returns_to_arrays():
    s = _state()
    before = s.as_floats()
    strapdown_step_fast(s, (1e-4, -2e-4, 3e-5), (1e-3, 2e-3, 0.049), 0.005, np.float64)
    x = s.as_floats()
    assert len(x) == 16 and x != before
    assert s.q.tolist() == list(x[0:4]) and s.pos.tolist() == list(x[7:10]) and s.f_n.tolist() == list(x[13:16])
    assert s.q.dtype == s.pos.dtype == np.float64
    with pytest.raises(ValueError):
        s.v[0] = 1.0  # the state's arrays are replaced, never written in place (D-10.F2)
    s.v = np.array([1.0, 2.0, 3.0])  # assignment: back to arrays, the other attributes keep their values
    assert s.as_floats()[4:7] == (1.0, 2.0, 3.0) and s.as_floats()[0:4] == x[0:4]
    c = s.copy()
    assert c.as_floats() == s.as_floats() and c.q is not s.q
    f = NavState(s.q.astype(np.float32), s.v.astype(np.float32), s.pos.copy(), 0.0, np.zeros(3, np.float32))
    strapdown_step(f, np.zeros(3, np.float32), np.array([0, 0, 0.049], np.float32), 0.005, dtype=np.float32)
    assert f.q.dtype == f.v.dtype == f.a_prev.dtype == f.f_n.dtype == np.float32 and f.pos.dtype == np.float64


@pytest.mark.parametrize("nav", ["float64", "float32"])
def test_firmware_steps_with_the_kernel_of_strapdown_step_fast(nav):
    """The 200 Hz loop picks the step of ``strapdown_step_fast`` for its nav precision once
    (``strapdown_kernel``, performance.md 5.7): the same kernel, hence the same bits, as the dispatching call."""
    from firmware_model import Firmware, FirmwareConfig
    from firmware_model.strapdown import strapdown_kernel

    fw = Firmware(FirmwareConfig(nav_state_precision=nav))
    dt = np.float64 if nav == "float64" else np.float32
    assert fw.core._strapdown is strapdown_kernel(dt)
    rng = np.random.default_rng(3)
    q = mat2q(a2mat(0.01, -0.02, 0.7))
    a = NavState(q.astype(dt), np.array([3.0, -1.0, 0.1], dtype=dt), np.array([0.7, 2.0, 50.0]), 0.0)
    b = NavState(q.astype(dt), np.array([3.0, -1.0, 0.1], dtype=dt), np.array([0.7, 2.0, 50.0]), 0.0)
    for _ in range(50):
        phi = rng.normal(0, 1e-3, 3).astype(dt).tolist()
        dv = rng.normal(0, 5e-2, 3).astype(dt).tolist()
        fw.core._strapdown(a, phi, dv, 0.005)
        strapdown_step_fast(b, phi, dv, 0.005, dt)
    assert a.as_floats() == b.as_floats()
