"""
The agent's 7 x 7 view of a MiniGrid world, as ``MiniGridEnv.gen_obs`` encodes it (Farama's ``minigrid``), in numba.

A world is a ``(width, height, 3)`` uint8 array of cell encodings (row ``n`` of a batch's ``grid``), indexed ``[x, y]``
like ``Grid.encode()``: an empty cell is ``(1, 0, 0)`` (``OBJECT_TO_IDX["empty"]``), a wall ``(2, 5, 0)``, a door
``(4, color, state)`` (state 0 open, 1 closed, 2 locked), a key ``(5, color, 0)``, a goal ``(8, 1, 0)``.
``write_view`` gives, for the agent at ``(x, y)`` facing ``direction``, what ``gen_obs_grid`` and
``Grid.encode(vis_mask)`` give: the view's cell ``(i, j)`` (``i`` across, ``j`` from the far row 0 to the agent's row
6, the agent at ``(3, 6)`` facing up) is the world's cell ``agent + forward * (6 - j) + right * (i - 3)``
(``get_view_coords`` inverted, which is the slice and the ``agent_dir + 1`` left rotations), a wall outside the world;
the same for any odd ``agent_view_size`` (``view``; the agent at ``(view // 2, view - 1)``);
with ``see_through_walls`` False, ``Grid.process_vis`` hides what walls and closed doors occlude (the cells it does not
reach are ``(0, 0, 0)``, "unseen"); the agent's own cell shows what it carries, else empty. The 147 values are written
in ``image.flatten()`` order, ``(i * 7 + j) * 3 + c``: the first 147 entries of ``FlatObsWrapper``'s vector (``view *
view * 3`` in ``(i * view + j) * 3 + c`` order for another view size).
"""

from __future__ import annotations

import numpy as np

from sb3_affect.kernel.jit import kernel_jit

VIEW = 7
VIEW_SIZE = VIEW * VIEW * 3
#: Object codes of ``minigrid.core.constants.OBJECT_TO_IDX`` the compiled worlds hold.
EMPTY, WALL, DOOR, KEY, GOAL = 1, 2, 4, 5, 8
#: ``COLOR_TO_IDX``: the goal's green, the door's and key's yellow, the wall's grey.
GREEN, YELLOW, GREY = 1, 4, 5
#: A door's state.
OPEN, CLOSED, LOCKED = 0, 1, 2
#: ``DIR_TO_VEC``: right, down, left, up.
DIR_X = np.array([1, 0, -1, 0], dtype=np.int64)
DIR_Y = np.array([0, 1, 0, -1], dtype=np.int64)


#: A flag on a view cell's state channel while ``_mark_visible`` runs (states are 0..2): the cell is visible.
_SEEN = 128


@kernel_jit
def _seen(out: np.ndarray, row: int, base: int) -> bool:
    return out[row, base + 2] >= _SEEN


@kernel_jit
def _opaque(out: np.ndarray, row: int, base: int) -> bool:
    """A cell the agent can not see behind (``not see_behind()``): a wall, a door not open."""
    kind = out[row, base]
    return kind == WALL or (kind == DOOR and out[row, base + 2] % _SEEN != OPEN)


@kernel_jit
def _mark(out: np.ndarray, row: int, base: int) -> None:
    if out[row, base + 2] < _SEEN:
        out[row, base + 2] += _SEEN


@kernel_jit
def _mark_visible(out: np.ndarray, row: int, view: int) -> None:
    """``Grid.process_vis`` on the view written at ``out[row]``, the agent at ``(view // 2, view - 1)``: flags the
    visible cells (``_SEEN``)."""
    _mark(out, row, ((view // 2) * view + view - 1) * 3)
    for j in range(view - 1, -1, -1):
        for i in range(view - 1):
            base = (i * view + j) * 3
            if not _seen(out, row, base) or _opaque(out, row, base):
                continue
            _mark(out, row, ((i + 1) * view + j) * 3)
            if j > 0:
                _mark(out, row, ((i + 1) * view + j - 1) * 3)
                _mark(out, row, (i * view + j - 1) * 3)
        for i in range(view - 1, 0, -1):
            base = (i * view + j) * 3
            if not _seen(out, row, base) or _opaque(out, row, base):
                continue
            _mark(out, row, ((i - 1) * view + j) * 3)
            if j > 0:
                _mark(out, row, ((i - 1) * view + j - 1) * 3)
                _mark(out, row, (i * view + j - 1) * 3)


@kernel_jit
def write_view(grid: np.ndarray, row: int, x: int, y: int, direction: int, carry: np.ndarray, see_through: bool,
               view: int, out: np.ndarray) -> None:
    """
    World ``grid[row]``'s agent's encoded ``view`` x ``view`` view (``view * view * 3`` uint8) into ``out[row]``'s
    first entries; ``carry[row]`` is the code of the object it carries (type 0: nothing).
    """
    width, height = grid.shape[1], grid.shape[2]
    dx, dy = DIR_X[direction], DIR_Y[direction]
    rx, ry = -dy, dx
    half = view // 2
    for i in range(view):
        for j in range(view):
            wx = x + dx * (view - 1 - j) + rx * (i - half)
            wy = y + dy * (view - 1 - j) + ry * (i - half)
            base = (i * view + j) * 3
            if 0 <= wx < width and 0 <= wy < height:
                out[row, base] = grid[row, wx, wy, 0]
                out[row, base + 1] = grid[row, wx, wy, 1]
                out[row, base + 2] = grid[row, wx, wy, 2]
            else:
                out[row, base] = WALL
                out[row, base + 1] = GREY
                out[row, base + 2] = 0
    if not see_through:
        _mark_visible(out, row, view)
        for base in range(0, view * view * 3, 3):
            if _seen(out, row, base):
                out[row, base + 2] -= _SEEN
            else:
                out[row, base] = 0
                out[row, base + 1] = 0
                out[row, base + 2] = 0
    base = (half * view + view - 1) * 3
    if carry[row, 0] != 0:
        out[row, base] = carry[row, 0]
        out[row, base + 1] = carry[row, 1]
        out[row, base + 2] = carry[row, 2]
    else:
        out[row, base] = EMPTY
        out[row, base + 1] = 0
        out[row, base + 2] = 0
