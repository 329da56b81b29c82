import numpy as np
import pytest

from pimm_env.sim.lidar import Lidar3DConfig, cast_rays, directions_3d
from pimm_env.sim.raycast import BulletRayCaster, EmbreeRayCaster, PrismRayCaster, _directions
from pimm_env.sim.scene import BulletScene
from pimm_env.world.files import load_world
from pimm_env.world.model import Element
from pimm_env.world.semantics import SemanticClass


@pytest.fixture(scope="module")
def iilab():
    world = load_world("iilab")
    scene = BulletScene(world, 0.25)
    yield world, scene
    scene.close()
    scene.close()  # closing twice is harmless


def test_directions_are_organized_and_unit():
    dirs = directions_3d(Lidar3DConfig())
    assert dirs.shape == (14400, 3)
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0)
    assert np.degrees(np.arcsin(dirs[:, 2])).min() == pytest.approx(-60.0)


def test_ray_directions_are_each_rays_own_sines_and_cosines_to_the_bit():
    rng = np.random.default_rng(0)
    azimuths, elevations = rng.uniform(-4, 4, 7), rng.uniform(-1, 1, 3)
    dirs = _directions(azimuths, elevations)
    for i, el in enumerate(elevations):
        for j, az in enumerate(azimuths):
            assert dirs[i, j].tolist() == [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]


def test_ray_batches_are_chunked(iilab):
    _, scene = iilab
    n = 16384 + 10
    origins = np.tile([-10.0, 4.2, 0.8], (n, 1))
    angles = np.linspace(-np.pi, np.pi, n)
    ends = origins + 10 * np.stack([np.cos(angles), np.sin(angles), np.zeros(n)], axis=1)
    fractions, bodies = cast_rays(scene.client, origins, ends)
    assert fractions.shape == (n,) and bodies.shape == (n,)
    head = cast_rays(scene.client, origins[:5000], ends[:5000])
    tail = cast_rays(scene.client, origins[5000:], ends[5000:])
    assert np.array_equal(bodies, np.concatenate([head[1], tail[1]]))
    assert np.array_equal(fractions, np.concatenate([head[0], tail[0]]))
    assert 0.5 < np.mean(bodies >= 0) < 1.0  # some rays run down the corridor beyond 10 m


def assert_agree(reference, other, origin):
    elevations = np.linspace(-np.pi / 3, np.pi / 3, 40)
    azimuths = -np.pi + 2 * np.pi * np.arange(360) / 360 + 0.3
    r_bullet, l_bullet = reference.cast(np.array(origin), azimuths, elevations, 10.0)
    r_prism, l_prism = other.cast(np.array(origin), azimuths, elevations, 10.0)
    assert np.mean(np.isfinite(r_bullet) == np.isfinite(r_prism)) > 0.999
    assert np.mean(l_bullet == l_prism) > 0.99
    both = np.isfinite(r_bullet) & np.isfinite(r_prism)
    assert np.percentile(np.abs(r_bullet[both] - r_prism[both]), 99) < 0.01


@pytest.mark.parametrize("origin", [[-10.0, 4.2, 0.8], [-24.0, 11.0, 0.8], [-20.0, 16.0, 0.8], [-26.0, 5.0, 0.8]])
@pytest.mark.parametrize("caster", [PrismRayCaster, EmbreeRayCaster])
def test_fast_casters_agree_with_pybullet(iilab, origin, caster):
    world, scene = iilab
    assert_agree(BulletRayCaster(scene.client, scene.body_classes), caster(world), origin)


def test_embree_agrees_with_pybullet_on_prisms_and_meshes(room_file):
    """A floor-plan world: walls as one prism with holes, a round post, a box; and the iilab's OBJ if present."""
    from pimm_env.world.shapes import Prism

    world = load_world(room_file)
    walls = Prism(np.array([[-1, -1], [7, -1], [7, 5], [-1, 5]]), (np.array([[0, 0], [6, 0], [6, 4], [0, 4]]),), (0, 3))
    world.elements[2:6] = [Element("walls", SemanticClass.WALL, walls, True)]
    scene = BulletScene(world, 0.25)
    try:
        for origin in ([1.0, 1.0, 0.5], [5.0, 3.0, 1.5]):
            assert_agree(BulletRayCaster(scene.client, scene.body_classes), EmbreeRayCaster(world), origin)
    finally:
        scene.close()


def test_prism_caster_single_box_range(room_file):
    world = load_world(room_file)
    ranges, labels = PrismRayCaster(world).cast(np.array([3.0, 2.0, 1.0]), np.array([0.0, np.pi]), np.zeros(1), 10.0)
    assert ranges[0, 1] == pytest.approx(3.0)  # west wall's inner face at x = 0
    assert ranges[0, 0] == pytest.approx(1.3)  # the post at x = 4.5, radius 0.2
    assert labels[0, 0] == 3 and labels[0, 1] == 0
    ranges, labels = PrismRayCaster(world).cast(np.array([3.0, 2.0, 1.0]), np.zeros(1), np.array([-np.pi / 4]), 10.0)
    assert ranges[0, 0] == pytest.approx(np.sqrt(2.0)) and labels[0, 0] == 2  # the floor


def test_embree_names_the_element_each_ray_hits_first(room_file):
    world = load_world(room_file)
    caster = EmbreeRayCaster(world)
    origin = np.array([3.0, 2.0, 1.0])
    directions = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    _, labels = caster.cast_directions(origin, directions, 10.0)
    elements = caster.cast_elements(origin, directions, 10.0)
    assert [world.elements[i].name for i in elements] == ["post", "west", "floor", "ceiling"]
    assert [world.elements[i].semantic for i in elements] == list(labels)
    assert caster.cast_elements(origin, directions, 0.5).tolist() == [-1] * 4  # nothing within 0.5 m
