import numpy as np
import pytest

from pimm_agents.particles.motion_model import odometry_delta, sample_differential


def test_delta_of_a_forward_move_and_a_turn():
    rot1, trans, rot2 = odometry_delta(np.array([1.0, 1.0, np.pi / 2]), np.array([1.0, 2.0, np.pi]))
    assert (rot1, trans, rot2) == pytest.approx((0.0, 1.0, np.pi / 2))
    rot1, trans, rot2 = odometry_delta(np.zeros(3), np.array([0.001, 0.0, 0.3]))
    assert rot1 == 0.0 and rot2 == pytest.approx(0.3)  # below 1 cm: a turn on the spot


def test_noise_free_model_moves_every_particle_by_the_odometry_in_its_own_frame():
    poses = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, np.pi / 2]])
    delta = odometry_delta(np.array([5.0, 5.0, 0.0]), np.array([6.0, 5.0, 0.2]))
    moved = sample_differential(poses, delta, (0.0, 0.0, 0.0, 0.0), np.random.default_rng(0))
    np.testing.assert_allclose(moved, [[1.0, 0.0, 0.2], [2.0, 2.0, np.pi / 2 + 0.2]], atol=1e-12)


def test_noise_grows_with_translation_and_is_centred():
    rng = np.random.default_rng(0)
    poses = np.zeros((20_000, 3))
    delta = odometry_delta(np.zeros(3), np.array([1.0, 0.0, 0.0]))
    moved = sample_differential(poses, delta, (0.2, 0.2, 0.2, 0.2), rng)
    travelled = np.hypot(moved[:, 0], moved[:, 1])
    assert travelled.mean() == pytest.approx(1.0, abs=0.02)
    assert travelled.std() == pytest.approx(np.sqrt(0.2), rel=0.1)  # variance alpha3 * trans^2
    # the heading of the move scatters with variance alpha2 * trans^2, so E[x] = exp(-0.2 / 2)
    assert moved[:, 0].mean() == pytest.approx(np.exp(-0.1), abs=0.02)
    assert np.abs(moved[:, 2]).max() <= np.pi
