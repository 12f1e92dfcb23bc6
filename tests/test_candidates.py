"""The contextual mode's candidates: the declared interface and its adapter."""

from __future__ import annotations

import numpy as np

from autonomy.types import Candidates, ComponentList, as_candidates
from sim.scenario import load_scenario
from sim.semantics import RobotFrameComponents, derive_components
from sim.types import Pose2D


def _view(rng: np.random.Generator) -> RobotFrameComponents:
    components = derive_components(load_scenario("cluttered_room"))
    pose = Pose2D(rng.uniform(1.0, 8.0), rng.uniform(1.0, 5.0), rng.uniform(-np.pi, np.pi))
    return RobotFrameComponents(components, pose)


def test_what_the_world_hands_out_is_candidates(rng):
    view = _view(rng)
    assert isinstance(view, Candidates)
    assert as_candidates(view) is view


def test_a_plain_sequence_is_adapted_with_the_same_target_points(rng):
    view = _view(rng)
    for plain in (tuple(view), list(view)):
        adapted = as_candidates(plain)
        assert isinstance(adapted, ComponentList)
        assert isinstance(adapted, Candidates)
        assert len(adapted) == len(view)
        k = int(rng.integers(len(view)))
        assert adapted[k].id == view[k].id
        np.testing.assert_allclose(adapted.target_points(), view.target_points(), atol=1e-12)


def test_no_components_gives_an_empty_target_array():
    assert as_candidates(()).target_points().shape == (0, 2)
