"""
Where the agent is: the cell the appraisal's known map (``act``) needs, for each env of a VecEnv.

The ``position=`` option of ``EmotionCallback``, ``BroekensCallback`` and the deep affective agents takes

* ``None`` (default): the observation is the cell, when the observation space has cells (``"discrete"`` or
  ``"multidiscrete"``); otherwise there is no map;
* ``"discrete"``: a Discrete observation is the cell (its integer, less the space's ``start``);
* ``"multidiscrete"``: a MultiDiscrete observation is the cell (its flat index), up to ``MAX_MAPPED_CELLS`` cells;
* ``"minigrid"`` or ``"minigrid-dir"``: a MiniGrid env's ``agent_pos`` (with ``agent_dir`` for ``"minigrid-dir"``),
  read through the VecEnv's ``get_attr`` whatever the observation wrapper;
* a callable ``position(observation, info) -> cell`` of one env's observation and info (any hashable cell; cells
  are numbered in the order they are first seen, up to ``MAX_MAPPED_CELLS``), called for each env at each step;
* ``BatchPosition(function)``: ``function(observations, infos) -> cells`` of the whole VecEnv, called once a step
  for all envs (a NumPy expression over the batch costs one call, not one per env);
* a ``Position`` instance (a subclass of your own).

The hooks read the cell after every env step. At the end of an episode the VecEnv has already reset, so the last
cell of the episode comes from ``info["terminal_observation"]`` for the observation presets and the callables; a
MiniGrid env keeps no record of it, so ``"minigrid"`` takes the cell in front of the agent when its last action was
``forward`` and ended the episode (the goal or lava it stepped on) and the cell it stood on otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

#: The largest number of cells a map is made for (the appraisal keeps a row per cell).
MAX_MAPPED_CELLS = 1_000_000
#: The presets of ``position=``.
POSITION_PRESETS = ("discrete", "multidiscrete", "minigrid", "minigrid-dir")

#: MiniGrid's ``forward`` action and its direction vectors (``minigrid.core.constants.DIR_TO_VEC``: right, down, left, up).
_MINIGRID_FORWARD = 2
_MINIGRID_TURNS = (0, 1)
_MINIGRID_DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))


class Position:
    """How the cell of each env of a VecEnv is found. Subclasses set ``n_cells`` in ``bind`` and give ``cells``."""

    name = "position"
    n_cells = 0

    def bind(self, venv: Any, observation_space: spaces.Space) -> None:
        """Check the env and set ``n_cells`` (called when training starts)."""

    def cells(self, venv: Any, observations: Any, infos: Sequence[dict[str, Any]]) -> list[int]:
        """Each env's current cell (after ``reset`` or ``step``: for an env that has just reset, its first cell)."""
        raise NotImplementedError

    def terminal_cell(self, index: int, info: dict[str, Any], cell: int, action: Any, terminated: bool) -> int:
        """
        The last cell of env ``index``'s episode that has just ended (``cell``: the cell before its last step), asked
        after ``cells`` has read the step's cells.
        """
        terminal = info.get("terminal_observation")
        return cell if terminal is None else self.cell_of(terminal, info)

    def cell_of(self, observation: Any, info: dict[str, Any] | None = None) -> int:
        """The cell of one env's observation (for the hooks that read it from the observation)."""
        raise NotImplementedError

    def is_move(self, action: Any) -> bool:
        """Whether an env step taking ``action`` is a move, an attempt to reach a neighbouring cell (every step here)."""
        return True


class ObservationCells(Position):
    """The observation is the cell: a Discrete space's integer, or a MultiDiscrete space's flat index."""

    def __init__(self, space: spaces.Space) -> None:
        self.start = 0
        self.nvec: np.ndarray | None = None
        if isinstance(space, spaces.Discrete):
            self.name = "discrete"
            self.n_cells = int(space.n)
            self.start = int(space.start)
        elif isinstance(space, spaces.MultiDiscrete):
            self.name = "multidiscrete"
            self.nvec = np.asarray(space.nvec, dtype=np.int64).reshape(-1)
            self.start_vec = np.asarray(getattr(space, "start", 0), dtype=np.int64).reshape(-1)
            self.n_cells = int(np.prod(self.nvec))
            if self.n_cells > MAX_MAPPED_CELLS:
                raise ValueError(
                    f"position='multidiscrete': the observation space has {self.n_cells:,} cells, more than the "
                    f"{MAX_MAPPED_CELLS:,} a map allows; pass position=callable(observation, info) -> cell"
                )
        else:
            raise TypeError(
                f"position: a {type(space).__name__} observation is not a cell; the observation presets take Discrete "
                "or MultiDiscrete spaces (use position='minigrid' or position=callable(observation, info) -> cell)"
            )

    def cell_of(self, observation: Any, info: dict[str, Any] | None = None) -> int:
        if self.nvec is None:
            return int(np.asarray(observation).reshape(-1)[0]) - self.start
        index = np.asarray(observation, dtype=np.int64).reshape(-1) - self.start_vec
        return int(np.ravel_multi_index(tuple(index), tuple(self.nvec)))

    def cells(self, venv: Any, observations: Any, infos: Sequence[dict[str, Any]]) -> list[int]:
        obs = np.asarray(observations)
        if self.nvec is None:
            flat = obs.reshape(-1)
            if not self.start and flat.dtype.kind in "iu":  # the cells as they are (the common case, once a step)
                return flat.tolist()
            return (flat.astype(np.int64) - self.start).tolist()
        return [self.cell_of(row) for row in obs.reshape(-1, len(self.nvec))]


class MiniGridPosition(Position):
    """A MiniGrid env's ``agent_pos`` (and ``agent_dir`` with ``direction=True``), read through ``venv.get_attr``."""

    def __init__(self, direction: bool = False) -> None:
        self.direction = direction
        self.name = "minigrid-dir" if direction else "minigrid"
        self.width = 0
        self._envs: list[Any] | None = None
        self._last: list[tuple[int, int, int]] = []  # each env's (x, y, direction) at the last reading
        self._before: list[tuple[int, int, int]] = []  # and at the one before it

    def bind(self, venv: Any, observation_space: spaces.Space) -> None:
        try:
            widths = venv.get_attr("width")
            heights = venv.get_attr("height")
            venv.get_attr("agent_pos")
        except AttributeError:
            raise ValueError(
                f"position={self.name!r}: the env has no agent_pos, width and height (is it a MiniGrid env?); pass "
                "position=callable(observation, info) -> cell for other envs"
            ) from None
        # a DummyVecEnv holds its envs: read them directly (get_attr walks each env's wrappers at every call)
        self._envs = [env.unwrapped for env in venv.envs] if isinstance(getattr(venv, "envs", None), list) else None
        self.width = max(int(w) for w in widths)
        self.n_cells = self.width * max(int(h) for h in heights) * (4 if self.direction else 1)

    def _cell(self, x: int, y: int, direction: int) -> int:
        cell = y * self.width + x
        return cell * 4 + direction if self.direction else cell

    def cells(self, venv: Any, observations: Any, infos: Sequence[dict[str, Any]]) -> list[int]:
        if self._envs is not None:
            last = [(int(env.agent_pos[0]), int(env.agent_pos[1]), int(env.agent_dir)) for env in self._envs]
        else:
            positions, directions = venv.get_attr("agent_pos"), venv.get_attr("agent_dir")
            last = [(int(p[0]), int(p[1]), int(d)) for p, d in zip(positions, directions)]
        self._before, self._last = self._last, last
        return [self._cell(*last) for last in self._last]

    def is_move(self, action: Any) -> bool:
        """``forward``, and under ``"minigrid-dir"`` the turns too; not pickup, drop, toggle or done."""
        value = int(np.asarray(action).reshape(-1)[0])
        return value == _MINIGRID_FORWARD or (self.direction and value in _MINIGRID_TURNS)

    def terminal_cell(self, index: int, info: dict[str, Any], cell: int, action: Any, terminated: bool) -> int:
        if not terminated or int(np.asarray(action).reshape(-1)[0]) != _MINIGRID_FORWARD or index >= len(self._before):
            return cell
        x, y, direction = self._before[index]
        dx, dy = _MINIGRID_DIRECTIONS[direction % 4]
        return self._cell(x + dx, y + dy, direction)


class NumberedPosition(Position):
    """Cells of a user's function, any hashable values: each distinct cell gets a number the first time it is seen."""

    def __init__(self, function: Callable[..., Any], default_name: str) -> None:
        self.function = function
        self.name = getattr(function, "__name__", default_name)
        self.n_cells = MAX_MAPPED_CELLS
        self.numbers: dict[Hashable, int] = {}

    def _number(self, cell: Any) -> int:
        if isinstance(cell, np.ndarray):
            cell = tuple(cell.reshape(-1).tolist())
        try:
            number = self.numbers.get(cell) if _finite(cell) else -1
        except TypeError:  # unhashable
            number = -1
        if number == -1:
            raise ValueError(
                f"position={self.name}: the callable returned {repr(cell)[:80]}, which is not a cell; a cell is a hashable "
                "value without NaN or infinity in it (e.g. an int, or a tuple of ints)"
            )
        if number is None:
            if len(self.numbers) >= MAX_MAPPED_CELLS:
                raise ValueError(f"position={self.name}: more than {MAX_MAPPED_CELLS:,} distinct cells; a map allows no more")
            number = self.numbers[cell] = len(self.numbers)
        return number


class CallablePosition(NumberedPosition):
    """``position(observation, info) -> cell`` of one env, called for each env at each step."""

    def __init__(self, function: Callable[[Any, dict[str, Any]], Hashable]) -> None:
        super().__init__(function, "callable")

    def cell_of(self, observation: Any, info: dict[str, Any] | None = None) -> int:
        return self._number(self.function(observation, {} if info is None else info))

    def cells(self, venv: Any, observations: Any, infos: Sequence[dict[str, Any]]) -> list[int]:
        if isinstance(observations, dict):
            n = len(next(iter(observations.values())))
            rows: list[Any] = [{key: value[index] for key, value in observations.items()} for index in range(n)]
        else:
            rows = list(np.asarray(observations))
        return [self.cell_of(row, infos[index] if index < len(infos) else {}) for index, row in enumerate(rows)]


class BatchPosition(NumberedPosition):
    """
    ``function(observations, infos) -> cells``: every env's cell from one call per VecEnv step, given the VecEnv's
    observations as they are (an array with a row per env, or a dict of such arrays) and its list of infos, and
    returning one cell per env (a sequence or an array: ints, or any hashable cells, numbered as a callable's are).
    A NumPy expression over the batch (``lambda obs, infos: obs[:, 2] > 0``) costs one call a step, not one per env.
    The last cell of an ended episode is the function of its ``terminal_observation`` as a batch of one.
    """

    def __init__(self, function: Callable[[Any, Sequence[dict[str, Any]]], Any]) -> None:
        if not callable(function):
            raise TypeError(f"BatchPosition needs a callable function(observations, infos) -> cells, got {function!r}")
        super().__init__(function, "batch")

    def cells(self, venv: Any, observations: Any, infos: Sequence[dict[str, Any]]) -> list[int]:
        cells = self.function(observations, infos)
        n = len(next(iter(observations.values()))) if isinstance(observations, dict) else len(observations)
        array = np.asarray(cells)
        if array.ndim == 0 or len(array) != n:
            raise ValueError(
                f"position={self.name}: the function returned {repr(cells)[:80]} for {n} envs; a BatchPosition "
                "function returns one cell per env (a sequence or an array of length n_envs)"
            )
        return [self._number(cell) for cell in (array.tolist() if array.ndim == 1 else array)]

    def cell_of(self, observation: Any, info: dict[str, Any] | None = None) -> int:
        if isinstance(observation, dict):
            batch: Any = {key: np.asarray(value)[None] for key, value in observation.items()}
        else:
            batch = np.asarray(observation)[None]
        return self.cells(None, batch, [{} if info is None else info])[0]


def _finite(cell: Any) -> bool:
    """Whether a cell holds no NaN or infinity (each NaN is a new dict key: every step would be a new cell)."""
    if isinstance(cell, (float, np.floating, complex)):
        return bool(np.isfinite(cell))
    if isinstance(cell, (tuple, frozenset)):
        return all(_finite(part) for part in cell)
    return True


PositionSpec = str | Callable[[Any, dict[str, Any]], Hashable] | Position | None


def check_position(position: PositionSpec) -> PositionSpec:
    """A ``position=`` value as given, or a one-line error naming what is allowed."""
    if position is None or isinstance(position, Position) or (callable(position) and not isinstance(position, str)):
        return position
    if isinstance(position, str) and position in POSITION_PRESETS:
        return position
    raise ValueError(
        f"position={position!r} is not supported; choose one of {', '.join(repr(p) for p in POSITION_PRESETS)}, None "
        "(the observation when it is a cell), a callable position(observation, info) -> cell or a Position"
    )


def make_position(position: PositionSpec, observation_space: spaces.Space) -> Position | None:
    """The hook of a ``position=`` value for an observation space; None when it has no cells and no hook was given."""
    position = check_position(position)
    if isinstance(position, Position):
        return position
    if position is None:
        try:
            return ObservationCells(observation_space)
        except (TypeError, ValueError):
            return None
    if isinstance(position, str):
        if position.startswith("minigrid"):
            return MiniGridPosition(direction=position == "minigrid-dir")
        cells = ObservationCells(observation_space)
        if cells.name != position:
            raise TypeError(f"position={position!r} needs a {position} observation space, got {observation_space}")
        return cells
    return CallablePosition(position)
