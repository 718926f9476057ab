"""``WorldBatch`` moves every copy exactly as a single ``World`` (and ``CommandedWorld``) moves."""

import numpy as np
import pytest

from infonav_gym.world import CircleObstacle, World, world_batch
from infonav_gym.world.active_scenarios import goal_field
from infonav_gym.world.scenarios import Route, Scenario, build_scenario
from infonav_gym.world.world_batch import WorldBatch

TIME_STEP_S = 0.5


class CommandedWorld(World):
    """A ``World`` whose robots follow velocity commands instead of waypoints.

    ``command(speeds, turn_rates)`` sets what each robot drives during the next
    ``step``; Pymunk still executes it (obstacles stop or deflect the robot) and
    ``step`` returns the executed motion, as for ``World``.
    """

    def reset(self, scenario: Scenario) -> None:
        super().reset(scenario)
        self._commands = [(0.0, 0.0)] * self.n_robots

    def command(self, speed_mps: float, turn_rate_rps: float, robot: int = 0) -> None:
        """Drive robot ``robot`` at ``speed_mps`` [m/s] and ``turn_rate_rps`` [rad/s] until the next command."""
        self._commands[robot] = (float(speed_mps), float(turn_rate_rps))

    def _waypoint_control(self, robot: int, x: float, y: float, heading: float) -> tuple[float, float]:
        return self._commands[robot]


def scenarios(name: str, seed: int, n_copies: int, **parameters) -> list[Scenario]:
    rng = np.random.default_rng(seed)
    return [build_scenario(name, rng, **parameters) for _ in range(n_copies)]


def crashing_scenario(offset: float) -> Scenario:
    """Two robots driving head-on into each other, then robot 0 into a wall: many Pymunk contact steps."""
    routes = (
        Route((offset, 0.0, 0.0), np.array([[20.0, 0.0]]), speed_mps=1.5),
        Route((10.0, 0.3, np.pi), np.array([[offset - 5.0, 0.0]]), speed_mps=1.0),
    )
    walls = (((13.0, -5.0), (13.0, 5.0)), ((-8.0, -5.0), (-8.0, 5.0)))
    return Scenario(name="crash", bounds=(-10.0, -10.0, 15.0, 10.0), routes=routes, walls=walls)


def assert_batch_follows_single_worlds(scenario_list: list[Scenario], n_steps: int, steps_of=None) -> None:
    """Step a batch and one World per scenario side by side; poses and executed controls equal to 1e-12."""
    batch = WorldBatch(len(scenario_list))
    singles = [World() for _ in scenario_list]
    for copy, (scenario, single) in enumerate(zip(scenario_list, singles)):
        batch.reset_copy(copy, scenario)
        single.reset(scenario)
    np.testing.assert_array_equal(batch.poses, [single.poses for single in singles])
    for step in range(n_steps):
        copies = np.arange(len(singles)) if steps_of is None else steps_of(step)
        executed = batch.step(TIME_STEP_S, copies)
        expected = np.reshape([singles[copy].step(TIME_STEP_S) for copy in copies.tolist()], executed.shape)
        np.testing.assert_allclose(executed, expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch.poses, [single.poses for single in singles], rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "name, parameters",
    [("field", {}), ("corridor", {}), ("team_field", {"n_robots": 4}), ("convoy", {"n_robots": 3})],
)
def test_every_copy_moves_as_a_single_world_on_the_builtin_scenarios(name, parameters):
    assert_batch_follows_single_worlds(scenarios(name, 3, 5, **parameters), n_steps=150)


def test_copies_in_contact_take_pymunk_steps_that_equal_the_single_worlds():
    batch_scenarios = [crashing_scenario(offset) for offset in (-6.0, -4.0, -2.0)]
    assert_batch_follows_single_worlds(batch_scenarios, n_steps=40)
    single = World()
    single.reset(batch_scenarios[0])
    for _ in range(40):
        single.step(TIME_STEP_S)
    assert single.poses[0, 0] < 13.0  # Pymunk stopped robot 0 at the wall before its waypoint (20, 0)


def lapping_scenario(offset: float) -> Scenario:
    """A robot lapping a square whose edges graze a wall and cross an obstacle: a run of contact steps each lap."""
    square = np.array([[8.0, 0.0], [8.0, 8.0], [0.0, 8.0], [0.0, offset]])
    routes = (Route((0.0, offset, 0.0), square, loop=True, speed_mps=1.2),)
    walls = (((-5.0, -0.6), (12.0, -0.6)),)
    obstacles = (CircleObstacle((4.0, 8.2), 0.5),)
    return Scenario(name="laps", bounds=(-10.0, -10.0, 15.0, 15.0), routes=routes, walls=walls, obstacles=obstacles)


@pytest.mark.parametrize("max_idle_spaces", [0, 64])
def test_runs_of_contact_steps_start_alike_in_a_kept_or_a_rebuilt_space(monkeypatch, max_idle_spaces):
    monkeypatch.setattr(world_batch, "MAX_IDLE_SPACES", max_idle_spaces)  # 0: every idle copy's space is dropped
    layouts = [lapping_scenario(offset) for offset in (0.0, -0.1, 0.1)]
    assert_batch_follows_single_worlds(layouts, n_steps=200)
    single, calls, in_contact = World(), [], []
    single.reset(layouts[0])
    drive = single.drive_in_contact
    monkeypatch.setattr(single, "drive_in_contact", lambda *args: calls.append(args) or drive(*args))
    for _ in range(200):
        before = len(calls)
        single.step(TIME_STEP_S)
        in_contact.append(len(calls) > before)
    runs = sum(1 for k, now in enumerate(in_contact) if now and (k == 0 or not in_contact[k - 1]))
    assert runs >= 4  # several separate runs, each after free steps


def test_stepping_some_copies_leaves_the_others_where_they_are():
    rng = np.random.default_rng(0)
    assert_batch_follows_single_worlds(
        scenarios("field", 1, 6), n_steps=60, steps_of=lambda step: np.flatnonzero(rng.random(6) < 0.5)
    )


def test_commanded_copies_move_as_a_commanded_world():
    rng = np.random.default_rng(7)
    layouts = [goal_field(rng) for _ in range(4)]
    batch, singles = WorldBatch(4), [CommandedWorld() for _ in layouts]
    for copy, (layout, single) in enumerate(zip(layouts, singles)):
        batch.reset_copy(copy, layout)
        single.reset(layout)
    for _ in range(120):
        commands = np.stack([rng.uniform(0.0, 2.0, 4), rng.uniform(-1.0, 1.0, 4)], axis=1)[:, None]
        executed = batch.step(TIME_STEP_S, np.arange(4), commands)
        for copy, single in enumerate(singles):
            single.command(*commands[copy, 0])
            np.testing.assert_allclose(executed[copy], single.step(TIME_STEP_S), rtol=0, atol=1e-12)
            np.testing.assert_allclose(batch.poses[copy], single.poses, rtol=0, atol=1e-12)


def test_a_team_driving_side_by_side_moves_as_commanded_worlds_through_near_misses_and_bumps(monkeypatch):
    """Four robots 2 m apart in a walled box, driven at random: robots within reach that stay apart take Pymunk's
    contact-free substeps in numpy, the others real contact steps (robots and walls), all alike."""
    rng = np.random.default_rng(3)
    routes = tuple(Route((7.0 + 2.0 * k, 10.0, rng.uniform(-3, 3)), np.zeros((0, 2))) for k in range(4))
    corners = [(0.0, 0.0), (24.0, 0.0), (24.0, 20.0), (0.0, 20.0)]
    walls = tuple(zip(corners, corners[1:] + corners[:1]))
    layout = Scenario(name="side by side", bounds=(0.0, 0.0, 24.0, 20.0), routes=routes, walls=walls)
    batch, singles = WorldBatch(3), [CommandedWorld() for _ in range(3)]
    for copy, single in enumerate(singles):
        batch.reset_copy(copy, layout)
        single.reset(layout)
    pymunk_steps, drive = [], World.drive_in_contact
    monkeypatch.setattr(
        World, "drive_in_contact", lambda world, *args: pymunk_steps.append(world) or drive(world, *args)
    )
    batch_steps = numpy_steps = 0  # the batch's Pymunk steps, and the singles' Pymunk steps it took in numpy
    for _ in range(300):
        commands = np.stack([rng.uniform(0.0, 1.0, (3, 4)), rng.uniform(-2.0, 2.0, (3, 4))], axis=-1)
        before = len(pymunk_steps)
        executed = batch.step(1.0, np.arange(3), commands)
        stepped = len(pymunk_steps) - before
        for copy, single in enumerate(singles):
            for robot in range(4):
                single.command(*commands[copy, robot], robot)
            np.testing.assert_allclose(executed[copy], single.step(1.0), rtol=0, atol=1e-12)
            np.testing.assert_allclose(batch.poses[copy], single.poses, rtol=0, atol=1e-12)
        batch_steps += stepped
        numpy_steps += len(pymunk_steps) - before - 2 * stepped
    assert numpy_steps > 20 and batch_steps > 20  # both kinds, many times


def test_a_copy_with_another_number_of_robots_is_a_clear_error():
    batch = WorldBatch(2)
    batch.reset_copy(0, scenarios("team_field", 0, 1, n_robots=3)[0])
    with pytest.raises(ValueError, match="copy 1: scenario 'team_field' has 4 robots, the other copies 3"):
        batch.reset_copy(1, scenarios("team_field", 0, 1, n_robots=4)[0])


@pytest.mark.parametrize("dt", [0.0, -1.0, 61.0])
def test_a_time_step_outside_its_range_is_a_clear_error(dt):
    batch = WorldBatch(1)
    batch.reset_copy(0, scenarios("field", 0, 1)[0])
    with pytest.raises(ValueError, match="dt"):
        batch.step(dt, np.arange(1))
