"""The simulator's site look: procedural table textures and the world built with them."""

from __future__ import annotations

import numpy as np
import pytest

from sim_bridge.params import PARAMETERS, SimBridgeParams
from sim_bridge.site_look import TEXTURE_KINDS, site_appearance, table_texture
from sim_bridge.world import PushWorld, WorldConfig


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_texture_is_seeded_and_textured(kind: str) -> None:
    a, b = table_texture(kind, 3, size=128), table_texture(kind, 3, size=128)
    assert a.shape == (128, 128, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, table_texture(kind, 4, size=128))
    assert a.reshape(-1, 3).std(axis=0).max() > 5.0  # not a uniform colour


def test_unknown_texture_and_look_refused() -> None:
    with pytest.raises(ValueError, match="table texture"):
        table_texture("marble", 0)
    with pytest.raises(ValueError, match="look"):
        WorldConfig(look="night")
    values = {s.name: s.default for s in PARAMETERS}
    values["appearance.look"] = "night"
    with pytest.raises(ValueError, match="appearance.look"):
        SimBridgeParams.from_values(values)


def test_site_look_draws_coloured_light_and_shadows() -> None:
    looks = [site_appearance(np.random.default_rng(s)) for s in range(20)]
    assert {look.table_texture for look in looks} == set(TEXTURE_KINDS)
    assert all(look.shadow and min(look.light_color) < 0.8 for look in looks)
    assert any(look.object_textured for look in looks)


def test_site_world_changes_the_look_not_the_scene() -> None:
    cfg = WorldConfig(object="butter", object_pose=(0.02, -0.03, 0.4), seed=5)
    with PushWorld(cfg) as world:
        plain = world.render()
        world.reset(WorldConfig(object="butter", object_pose=(0.02, -0.03, 0.4), seed=5,
                                look="site"))
        site = world.render()
        again = world.render()
    np.testing.assert_array_equal(site.mask, plain.mask)
    np.testing.assert_allclose(site.depth, plain.depth, equal_nan=True)
    table = ~plain.mask & np.isfinite(plain.depth)
    assert site.rgb[table].std(axis=0).max() > 3 * plain.rgb[table].std(axis=0).max()
    np.testing.assert_array_equal(again.mask, site.mask)
