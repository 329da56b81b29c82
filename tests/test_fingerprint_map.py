import numpy as np
import pytest

from pimm_agents.measurement.perception_quality import retrieval_errors
from pimm_agents.perception.fingerprint_map import FingerprintConfig, FingerprintMap
from pimm_agents.perception.records import FINGERPRINTS, write_record


def line_map(n: int = 20, dim: int = 8) -> FingerprintMap:
    """Positions 1 m apart along x; descriptor i is a unit vector that turns slowly with i."""
    angle = np.linspace(0, np.pi / 2, n)
    descriptors = np.zeros((n, dim), dtype=np.float32)
    descriptors[:, 0], descriptors[:, 1] = np.cos(angle), np.sin(angle)
    positions = np.column_stack([np.arange(n, dtype=float), np.zeros(n)])
    return FingerprintMap(descriptors, positions)


def test_query_returns_the_nearest_positions_and_passes_the_spread_check():
    fmap = line_map()
    result = fmap.query(fmap.descriptors[7])
    assert result.positions[0].tolist() == [7.0, 0.0]
    assert sorted(result.positions[:, 0].tolist()) == [6.0, 7.0, 8.0]
    assert result.consistent and len(result.suggestions) == 3
    assert result.distances[0] == pytest.approx(0.0, abs=1e-6)


def test_spread_check_drops_contradictory_suggestions():
    fmap = line_map()
    positions = fmap.positions.copy()
    positions[8] = [30.0, 0.0]  # a look-alike place far away
    far = FingerprintMap(fmap.descriptors, positions, config=FingerprintConfig(k=3, max_spread=10.0))
    result = far.query(fmap.descriptors[7])
    assert result.spread > 10.0 and not result.consistent
    assert result.suggestions.shape == (0, 2)


def test_save_and_load_round_trip(tmp_path):
    fmap = line_map()
    path = tmp_path / "fingerprints.npz"
    fmap.save(path, "ab" * 32, {"spacing_m": "1.0"})
    again = FingerprintMap.load(path, weights_sha256="ab" * 32)
    assert np.array_equal(again.descriptors, fmap.descriptors) and np.array_equal(again.positions, fmap.positions)
    assert again.query(fmap.descriptors[3]).positions[0].tolist() == [3.0, 0.0]


def test_bad_maps_and_queries_are_named(tmp_path):
    fmap = line_map()
    with pytest.raises(ValueError, match="8 dimensions|query descriptor has 5 dimensions"):
        fmap.query(np.ones(5))
    with pytest.raises(ValueError, match="NaN"):
        fmap.query(np.full(8, np.nan))
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        FingerprintMap.load(tmp_path / "missing.npz")
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not a zip file")
    write_record(broken, FINGERPRINTS, "pimm-fingerprints/1")  # recorded as it is: the reading itself must fail
    with pytest.raises(ValueError, match="broken.npz: not a readable fingerprint map"):
        FingerprintMap.load(broken)
    np.savez(tmp_path / "partial.npz", format="pimm-fingerprints/1", descriptors=np.ones((3, 2)))
    write_record(tmp_path / "partial.npz", FINGERPRINTS, "pimm-fingerprints/1")
    with pytest.raises(ValueError, match=r"lacks field\(s\) \['positions', 'headings'\]"):
        FingerprintMap.load(tmp_path / "partial.npz")
    with pytest.raises(ValueError, match="positions"):
        FingerprintMap(np.ones((4, 2)), np.ones((3, 2)))
    with pytest.raises(ValueError, match="k = 3"):
        FingerprintMap(np.ones((2, 2)), np.ones((2, 2)))


def test_retrieval_errors_by_hand():
    fmap = line_map()
    results = [fmap.query(fmap.descriptors[5]), fmap.query(fmap.descriptors[15])]
    truths = np.array([[5.0, 0.0, 0.0], [11.5, 0.0, 0.0]])  # the second: 2.5 m from its best match
    errors = retrieval_errors(results, truths)
    assert errors["recall_at_3_2m"] == 0.5
    assert errors["mean_min_error_m"] == pytest.approx((0 + 2.5) / 2)
    assert errors["mean_max_error_m"] == pytest.approx((1 + 4.5) / 2)
    assert errors["mean_error_m"] == pytest.approx(((0 + 1 + 1) / 3 + (2.5 + 3.5 + 4.5) / 3) / 2)


def test_a_truncated_fingerprint_map_is_named(tmp_path):
    from pathlib import Path

    source = Path(__file__).resolve().parents[1] / "maps" / "iilab" / "fingerprints.npz"
    for keep in (5000, source.stat().st_size - 100):
        cut = tmp_path / f"cut{keep}.npz"
        cut.write_bytes(source.read_bytes()[:keep])
        cut.with_suffix(".json").write_bytes(source.with_suffix(".json").read_bytes())
        with pytest.raises(ValueError, match=f"cut{keep}.npz: SHA-256 .* differs from cut{keep}.json"):
            FingerprintMap.load(cut)
        write_record(cut, FINGERPRINTS, "pimm-fingerprints/1")  # even recorded as cut, it cannot be read
        with pytest.raises(ValueError, match=f"cut{keep}.npz: .*damaged or truncated"):
            FingerprintMap.load(cut)


def test_a_map_without_a_matching_record_is_refused(tmp_path):
    """The two holes a bad-input campaign found: a map rescaled and stored as int64 loaded without a word, and
    nothing tied a map to the weights that made it."""
    fmap = line_map()
    path = tmp_path / "fingerprints.npz"
    fmap.save(path, "ab" * 32)
    with pytest.raises(ValueError, match=r"made with weights abababab.*, the segmenter runs cdcdcdcd"):
        FingerprintMap.load(path, weights_sha256="cd" * 32)
    scaled = tmp_path / "scaled.npz"
    arrays = {"descriptors": (fmap.descriptors * 100).astype(np.int64), "positions": fmap.positions}
    np.savez(scaled, format="pimm-fingerprints/1", headings=fmap.headings, **arrays)
    with pytest.raises(ValueError, match=r"scaled.npz: no record scaled.json beside it"):
        FingerprintMap.load(scaled)
    path.with_suffix(".json").rename(scaled.with_suffix(".json"))  # another file's record
    with pytest.raises(ValueError, match=r"scaled.npz: SHA-256 .* differs from scaled.json"):
        FingerprintMap.load(scaled)
    write_record(scaled, FINGERPRINTS, "pimm-fingerprints/1", dtype="int64", shape=[20, 8], weights_sha256="ab" * 32)
    with pytest.raises(ValueError, match=r"scaled.npz: descriptors stored as int64, the record says int64; .* float32"):
        FingerprintMap.load(scaled)
    np.savez(
        scaled,
        format="pimm-fingerprints/1",
        headings=fmap.headings,
        descriptors=fmap.descriptors * 100,
        positions=fmap.positions,
    )
    write_record(scaled, FINGERPRINTS, "pimm-fingerprints/1", dtype="float32", shape=[20, 8], weights_sha256="ab" * 32)
    with pytest.raises(ValueError, match=r"scaled.npz: descriptor lengths 100-100, expected 1"):
        FingerprintMap.load(scaled)
    write_record(scaled, FINGERPRINTS, "pimm-fingerprints/1", dtype="float32", shape=[21, 8], weights_sha256="ab" * 32)
    with pytest.raises(ValueError, match=r"scaled.npz: descriptors of shape \(20, 8\), the record says \[21, 8\]"):
        FingerprintMap.load(scaled)


def test_places_that_see_nothing_within_range_get_no_fingerprint_and_are_counted(tmp_path):
    from pimm_agents.perception.files import SHIPPED_WEIGHTS
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.preparation.fingerprints import build_fingerprint_map
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    world = tmp_path / "far" / "world.yaml"  # a floor seen only near its one room: 20 m of it beyond the LiDAR
    world.parent.mkdir()
    world.write_text(
        "format: pimm-world/1\nname: far\nfloor_z: 0.0\nareas:\n  all: [[0, 0], [26, 0], [26, 4], [0, 4]]\n"
        "elements:\n"
        "  - {name: floor, class: floor, box: {min: [-0.5, -0.5, -0.1], max: [6.5, 4.5, 0.0]}}\n"
        "  - {name: ceiling, class: ceiling, box: {min: [-0.5, -0.5, 3.0], max: [6.5, 4.5, 3.1]}}\n"
        "  - {name: west, class: wall, box: {min: [-0.2, 0.0, 0.0], max: [0.0, 4.0, 3.0]}}\n"
        "  - {name: south, class: wall, box: {min: [-0.2, -0.2, 0.0], max: [6.2, 0.0, 3.0]}}\n"
    )
    ensure_derived_maps(load_world(world))
    with pytest.warns(UserWarning, match=r"world 'far': \d+ of \d+ fingerprint places saw nothing"):
        fmap = build_fingerprint_map(str(world), load_segmenter(SHIPPED_WEIGHTS), 2.0, progress=False)
    assert 3 <= len(fmap) and fmap.positions[:, 0].max() < 17.0 and np.isfinite(fmap.descriptors).all()
