"""Experiment YAMLs: every kind of bad input is rejected before anything runs, naming the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from sb3_affect.study.cli import main
from sb3_affect.study.launcher import SweepError, load_sweep
from sb3_affect.study.launcher.schema import derive_seed
from sb3_affect.study.launcher.sweep_file import load_sweep_file

EXPERIMENTS = Path(__file__).resolve().parents[3] / "experiments"

GOOD = """\
name: tiny
env: {id: sb3_affect/GridPursuit-v0, kwargs: {size: 5, goal: [2, 2]}}
episodes: 5
seeds: 2
agents:
  - name: q
    algo: QLearning
    grid: {epsilon: [0.1, 0.5]}
    kwargs: {exploration_rate: $epsilon}
  - name: affective
    algo: AffectQ
    grid: {epsilon: [0.1, 0.5]}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def error_of(tmp_path: Path, text: str, overrides: tuple[str, ...] = ()) -> str:
    path = write(tmp_path, text)
    with pytest.raises(SweepError) as info:
        load_sweep(path, overrides)
    message = str(info.value)
    assert str(path) in message, message
    return message


def test_good_file_resolves_runs(tmp_path: Path) -> None:
    sweep = load_sweep(write(tmp_path, GOOD))
    configs = sweep.run_configs()
    assert len(configs) == 8
    q = [c for c in configs if c["agent"] == "q"]
    assert sorted({c["algo_kwargs"]["exploration_rate"] for c in q}) == [0.1, 0.5]
    affective = [c for c in configs if c["agent"] == "affective"]
    assert all(c["algo_kwargs"] == {} for c in affective)
    # The affective agent runs once per epsilon label, each with its own seeds; every seed differs.
    assert sorted(c["labels"]["epsilon"] for c in affective) == [0.1, 0.1, 0.5, 0.5]
    assert len({c["seed"] for c in configs}) == len(configs)
    # Seeds are stable (sha256 of sweep, agent, grid point, replicate), not Python's salted hash().
    assert load_sweep(write(tmp_path, GOOD)).run_configs() == configs
    assert derive_seed("tiny", "q", {"epsilon": 0.1}, 0) == q[0]["seed"]
    assert derive_seed("tiny", "q", {"epsilon": 0.1}, 0) == 1565592802


@pytest.mark.parametrize(
    "text, key, hint",
    [
        (GOOD.replace("episodes: 5", "episodes: 5\nepisodez: 7"), "episodez", "Extra inputs are not permitted"),
        (GOOD.replace("    algo: QLearning\n", "    algo: QLearning\n    kwarg: {}\n"), "agents[0] (q).kwarg", "Extra inputs"),
        (GOOD.replace("kwargs: {size: 5, goal: [2, 2]}}", "kwargs: {}, version: 2}"), "env.version", "Extra inputs"),
        (GOOD.replace("episodes: 5", "episodes: many"), "episodes", "'many'"),
        (GOOD.replace("episodes: 5", "episodes: 0"), "episodes", "greater than 0"),
        (GOOD.replace("episodes: 5", "episodes: -3"), "episodes", "greater than 0"),
        (GOOD.replace("seeds: 2", "seeds: 0"), "seeds", "positive"),
        (GOOD.replace("seeds: 2", "seeds: []"), "seeds", "non-empty"),
        (GOOD.replace("seeds: 2", "seeds: [1, 1]"), "seeds", "distinct"),
        (GOOD.replace("grid: {epsilon: [0.1, 0.5]}\n    kwargs", "grid: {epsilon: []}\n    kwargs"), "grid", "empty"),
        (GOOD.replace("grid: {epsilon:", "grid: {agent: [a], epsilon:"), "agents[0] (q).grid", "'agent' names a column"),
        (GOOD.replace("grid: {epsilon:", "grid: {seed: [7], epsilon:"), "grid", "'seed' names a column"),
        (GOOD.replace("grid: {epsilon:", "grid: {reward: [1], epsilon:"), "grid", "'reward' names a column"),
        (GOOD.replace("algo: QLearning", "algo: QLearnin"), "agents[0] (q).algo", "QLearnin"),
        (GOOD.replace("algo: QLearning", "algo: nosuchpkg.mod:Agent"), "agents[0] (q).algo", "can not be imported"),
        (GOOD.replace("algo: QLearning", "algo: sb3_affect:NoSuchAgent"), "agents[0] (q).algo", "no class"),
        (GOOD.replace("id: sb3_affect/GridPursuit-v0", "id: sb3_affect/GridPursuit-v9"), "env.id", "not registered"),
        (GOOD.replace("$epsilon", "$eps"), "agents[0] (q)", "refers to no grid label"),
        (GOOD.replace("name: tiny", "name: 'a b/c'"), "name", "pattern"),
        (GOOD.replace("  - name: q", "  - name: '.q'"), "agents[0]", "pattern"),
        (GOOD.replace("  - name: q", "  - name: 'q/r'"), "agents[0]", "pattern"),
        (GOOD.replace("    kwargs: {exploration_rate", "    seeds_by: [task]\n    kwargs: {exploration_rate"), "agents[0]",
         "seeds_by: [task] needs tasks"),
        (GOOD.replace("    kwargs: {exploration_rate", "    seeds_by: [eps]\n    kwargs: {exploration_rate"), "agents[0]",
         "'eps' is not a label of the agent"),
        (GOOD.replace("    grid: {epsilon: [0.1, 0.5]}\n    kwargs", "    grid_by_task: {a: {epsilon: [0.1]}}\n    kwargs"),
         "agents[0] (q)", "grid_by_task needs tasks"),
        (GOOD.replace("  - name: affective", "  - name: q"), "agents", "unique"),
        (GOOD.replace("max_timesteps", "x") + "max_timesteps: 0\n", "max_timesteps", "greater than 0"),
        (GOOD + "logs: [csv, excel]\n", "logs", "excel"),
        ("name: x\nepisodes: 5\nseeds: 1\n", "agents", "agents is missing or empty: a sweep of runs needs episodes, "),
        ("name: x\nepisodes: 5\nseeds: 1\nagents: []\n", "agents", "agents is missing or empty"),
        ("name: x\nseeds: 1\nagents: [{name: q, algo: QLearning}]\n", "episodes", "episodes is missing: a sweep of "),
    ],
)
def test_schema_errors_name_the_key(tmp_path: Path, text: str, key: str, hint: str) -> None:
    message = error_of(tmp_path, text)
    assert key in message, message
    assert hint in message, message


@pytest.mark.parametrize(
    "text, key, hint",
    [
        (GOOD.replace("$epsilon}", "$epsilon, exploraton_rate: 0.1}"), "agents[0] (q).kwargs", "exploraton_rate"),
        (GOOD.replace("[0.1, 0.5]}\n    kwargs", "[0.1, 1.5]}\n    kwargs"), "agents[0] (q).kwargs", "exploration_rate=1.5"),
        (GOOD + "    kwargs: {comparison: sideways}\n", "agents[1] (affective).kwargs", "'literal', 'valence'"),
        (GOOD.replace("size: 5", "size: 1"), "env.kwargs", "size"),
        (GOOD.replace("size: 5", "sise: 5"), "env.kwargs", "sise"),
    ],
)
def test_impossible_kwargs_are_rejected_before_anything_runs(tmp_path: Path, text: str, key: str, hint: str) -> None:
    message = error_of(tmp_path, text)
    assert key in message and hint in message, message
    assert "can not be built" in message, message


def test_malformed_yaml_reports_the_line(tmp_path: Path) -> None:
    text = GOOD.replace("seeds: 2", "seeds: [2")
    message = error_of(tmp_path, text)
    assert "malformed YAML" in message and "line" in message, message
    assert "line 5" in message or "line 6" in message, message


def test_not_a_mapping_and_unsafe_tags(tmp_path: Path) -> None:
    assert "mapping" in error_of(tmp_path, "- just\n- a list\n")
    # The safe loader refuses Python tags: nothing is constructed, nothing executed.
    message = error_of(tmp_path, "name: !!python/object/apply:os.system ['touch pwned']\n")
    assert "malformed YAML" in message
    assert not (tmp_path / "pwned").exists()


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SweepError, match="can not read"):
        load_sweep(tmp_path / "nope.yaml")


def test_overrides(tmp_path: Path) -> None:
    path = write(tmp_path, GOOD)
    sweep = load_sweep(path, ("seeds=3", "agents.0.kwargs.gamma=0.9", "env.kwargs.size=6"))
    configs = sweep.run_configs()
    assert len(configs) == 12
    assert all(c["algo_kwargs"]["gamma"] == 0.9 for c in configs if c["agent"] == "q")
    assert all(c["env_kwargs"]["size"] == 6 for c in configs)
    # An override is validated like the file.
    assert "seeds" in error_of(tmp_path, GOOD, ("seeds=0",))
    assert "key=value" in error_of(tmp_path, GOOD, ("seeds",))
    assert "no agent '7'" in error_of(tmp_path, GOOD, ("agents.7.kwargs.gamma=1",))


def test_cli_reports_schema_error_without_running(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, GOOD.replace("episodes: 5", "episodes: 0"))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "episodes" in err and str(path) in err
    assert not out.exists()


@pytest.mark.parametrize(
    "name, runs, agents",
    [
        ("paper.yaml", 360, {"epsilon-greedy": 180, "affective": 180}),
        ("smoke.yaml", 8, {"epsilon-greedy": 4, "affective": 4}),
        ("dqn.yaml", 30, {"dqn-const": 10, "dqn-sb3-exploration-schedule": 5, "epsilon-greedy": 10, "affective": 5}),
        ("ablation.yaml", 1440, {"affective": 1440}),
    ],
)
def test_shipped_files(name: str, runs: int, agents: dict[str, int]) -> None:
    sweep = load_sweep(EXPERIMENTS / name)
    configs = sweep.run_configs()
    assert len(configs) == runs
    assert {a: sum(c["agent"] == a for c in configs) for a in agents} == agents
    if name != "dqn.yaml":
        assert len({c["seed"] for c in configs}) == runs
    if name == "dqn.yaml":  # equal seeds: every agent configuration runs on seeds 0-4
        by_config: dict[str, set[int]] = {}
        for c in configs:
            point = {k: v for k, v in c["labels"].items() if k != "replicate"}
            by_config.setdefault(f"{c['agent']} {point}", set()).add(c["seed"])
        assert all(seeds == {0, 1, 2, 3, 4} for seeds in by_config.values())
        const = [c for c in configs if c["agent"] == "dqn-const"]
        assert all(
            c["algo_kwargs"]["exploration_initial_eps"] == c["algo_kwargs"]["exploration_final_eps"] == c["labels"]["epsilon"]
            for c in const
        )
        assert sorted({c["labels"]["epsilon"] for c in const}) == [0.1, 0.9]
        assert all(c["max_timesteps"] and c["episodes"] == 200 for c in configs)
    if name == "ablation.yaml":
        readings = {(c["algo_kwargs"]["comparison"], c["algo_kwargs"]["act"], c["algo_kwargs"]["units"]) for c in configs}
        assert len(readings) == 8
        assert sorted({c["labels"]["epsilon"] for c in configs}) == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]


def test_env_of_your_own_as_module_colon_id(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "my_sweep_envs.py").write_text(
        "import gymnasium as gym\n"
        "gym.register(id='MyPursuit-v0', entry_point='sb3_affect.envs.grid_pursuit:GridPursuitEnv',\n"
        "             kwargs={'size': 5, 'goal': (2, 2)})\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    text = GOOD.replace(
        "env: {id: sb3_affect/GridPursuit-v0, kwargs: {size: 5, goal: [2, 2]}}", "env: {id: 'my_sweep_envs:MyPursuit-v0'}"
    )
    configs = load_sweep(write(tmp_path, text)).run_configs()
    assert {c["env_id"] for c in configs} == {"my_sweep_envs:MyPursuit-v0"}
    from sb3_affect.study.launcher import execute_run

    result = execute_run({**configs[0], "episodes": 2})
    assert len(result["episodes"]["episode"]) == 2 and result["episodes"]["optimal"] is not None
    assert "module 'no_such_module' can not be imported" in error_of(tmp_path, text.replace("my_sweep_envs", "no_such_module"))
    assert "'your_module:YourEnv-v0'" in error_of(tmp_path, text.replace("MyPursuit-v0", "Other-v0"))


TASKS = """\
name: tasks
tasks:
  "static grid (the paper's)": {id: sb3_affect/GridPursuit-v0, kwargs: {size: 5, goal: [2, 2]}}
  "maze: wall": {id: sb3_affect/MazePursuit-v0, kwargs: {maze: wall}}
episodes: 5
seeds: 3
agents:
  - name: epsilon-greedy, tuned ε
    algo: QLearning
    seeds_by: [task]
    grid_by_task: {"maze: wall": {epsilon: [0.2, 0.3]}}
    kwargs: {exploration_rate: $epsilon}
  - name: fixed 0.1
    algo: QLearning
    seeds_by: [task]
    kwargs: {exploration_rate: 0.1}
"""


def test_a_grid_per_task_and_seeds_by_task(tmp_path: Path) -> None:
    """
    ``grid_by_task`` runs an agent on the tasks it names, each with its grid; ``seeds_by: [task]`` derives its seeds
    from the task alone (the same for every ε, another per task); names may be text (spaces, commas, ε, a colon).
    """
    sweep = load_sweep(write(tmp_path, TASKS), build=False)
    cells = [(c.base["agent"], c.base["labels"], c.seeds) for c in sweep.cells()]
    tuned, fixed = "epsilon-greedy, tuned ε", "fixed 0.1"
    assert [(a, labels) for a, labels, _ in cells] == [
        (fixed, {"task": "static grid (the paper's)"}),
        (tuned, {"epsilon": 0.2, "task": "maze: wall"}),
        (tuned, {"epsilon": 0.3, "task": "maze: wall"}),
        (fixed, {"task": "maze: wall"}),
    ]
    assert cells[1][2] == cells[2][2] == [derive_seed("tasks", tuned, {"task": "maze: wall"}, r) for r in range(3)]
    assert cells[0][2] == [derive_seed("tasks", fixed, {"task": "static grid (the paper's)"}, r) for r in range(3)]
    assert cells[3][2] != cells[0][2] and len(sweep.run_configs()) == 12
    dumped = load_sweep(write(tmp_path, GOOD), build=False).model_dump(mode="json")
    assert "grid_by_task" not in dumped["agents"][0] and "seeds_by" not in dumped["agents"][0]  # old folders resume
    both = TASKS.replace("    seeds_by: [task]\n    grid_by_task", "    grid: {epsilon: [0.1]}\n    grid_by_task", 1)
    assert "either grid or grid_by_task" in error_of(tmp_path, both)
    unknown = TASKS.replace('grid_by_task: {"maze: wall"', 'grid_by_task: {"maze: hall"')
    assert "grid_by_task names 'maze: hall', not a task of the sweep" in error_of(tmp_path, unknown)
    assert "is not a task name" in error_of(tmp_path, TASKS.replace('"maze: wall":', '"maze/wall":', 1))


FORENSICS = """\
name: tiny-forensics
forensics:
  screen_reps: 2
  leaders: 1
  reps: 3
  alphas: [1.0]
  gammas: [0.8]
"""


def test_a_forensics_study_file_validates_and_is_no_sweep_of_runs(tmp_path: Path) -> None:
    study = load_sweep_file(write(tmp_path, FORENSICS))
    assert study.kind == "forensics" and study.forensics is not None
    block = study.forensics
    assert (block.screen_reps, block.leaders, block.reps, block.alphas, block.gammas) == (2, 1, 3, [1.0], [0.8])
    assert block.protocol.model_dump() == {"epsilons": None, "seeds": None, "episodes": None}  # the paper's
    sets = ["forensics.reps=5", "forensics.protocol.seeds=2", "forensics.gammas=[0.7, 0.9]"]
    overridden = load_sweep_file(write(tmp_path, FORENSICS), sets).forensics
    assert overridden is not None and (overridden.reps, overridden.protocol.seeds, overridden.gammas) == (5, 2, [0.7, 0.9])
    with pytest.raises(SweepError, match=r"the forensics study has no runs of its own; run it with `sb3-affect run"):
        load_sweep(write(tmp_path, FORENSICS))


@pytest.mark.parametrize(
    "change, overrides, expected",
    [
        (("reps: 3", "reps: 1"), (), "  forensics.reps: Input should be greater than or equal to 2 (got 1)\n"),
        (("alphas: [1.0]", "alphas: [0.0]"), (), "  forensics.alphas: 0.0 is not a learning rate; each is in (0, 1]\n"),
        (("  gammas: [0.8]", "  gammas: [0.8]\nepisodes: 5"), (),
         "  (top level): episodes is not a key of the forensics (a sweep with forensics); its keys are name, forensics\n"),
        (("", ""), ("forensics.screen_reps=4",), "  forensics.reps: fewer than screen_reps (4); give reps >= 4 (got 3)\n"),
        (("", ""), ("forensics.protocol.epsilons=[0.5]",),
         "  forensics.protocol.epsilons: List should have at least 2 items after validation"),
        (("", ""), ("forensics.protocol.epsilons=[0.5, 1.5]",),
         "  forensics.protocol.epsilons: 1.5 is not an ε; each is in [0, 1] [from --set"),
    ],
)
def test_a_bad_forensics_field_is_one_line_naming_it_its_value_and_what_is_allowed(
    tmp_path: Path, change: tuple[str, str], overrides: tuple[str, ...], expected: str
) -> None:
    message = error_of(tmp_path, FORENSICS.replace(*change), overrides)
    assert expected in message, message
    allowed = "  (allowed top-level keys of the forensics (a sweep with forensics): name, forensics)"
    assert message.splitlines()[-1] == allowed
    assert len(message.splitlines()) == 3, message  # the file, the one bad field, the keys allowed


def test_a_forensics_set_typo_names_the_keys_allowed(tmp_path: Path) -> None:
    message = error_of(tmp_path, FORENSICS, ("forensics.rep=3",))
    assert "'rep' is not a key of forensics; did you mean 'reps'? (allowed: screen_reps, leaders, reps, " in message
    seed = error_of(tmp_path, FORENSICS, ("forensics.protocol.seed=2",))
    assert "'seed' is not a key of forensics.protocol; did you mean 'seeds'?" in seed
    single = error_of(tmp_path, FORENSICS, ("forensics.reps.x=2",))
    assert "'forensics.reps' is a single value; use --set forensics.reps=VALUE" in single
    old = "'reps' is not a key of the forensics (a sweep with forensics); did you mean 'forensics.reps'? (allowed: name, "
    assert old in error_of(tmp_path, FORENSICS, ("reps=3",))
    deep = "'episodes' is not a key of the forensics (a sweep with forensics) (allowed: name, forensics)"
    assert deep in error_of(tmp_path, FORENSICS, ("episodes=3",))
