"""
SB3's default Q-network evaluated in numpy, on the network's own parameters: what an observer needs at every step
without the fixed cost of a torch forward pass (on a small MLP that cost is most of a step's work).

Only the common case is mirrored: a ``QNetwork`` (DQN) whose features extractor is SB3's ``FlattenExtractor`` on a
``Discrete`` or a non-image ``Box`` observation space, its head a ``Sequential`` of ``Linear`` layers and ReLU or Tanh
activations, on the CPU. The arrays are views of the parameters (``Tensor.numpy()`` shares their memory), so the
mirror follows every in-place update of the optimiser and of ``load_state_dict`` without a copy. Anything else
(another extractor, images, a GPU, a parameter replaced) gets None from ``q_values_fn`` or ``stale``, and the caller
uses torch.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.preprocessing import is_image_space
from stable_baselines3.common.torch_layers import FlattenExtractor

#: The activations mirrored, by torch class.
ACTIVATIONS: dict[type, Callable[[np.ndarray], np.ndarray]] = {
    th.nn.ReLU: lambda x: np.maximum(x, 0.0, out=x),
    th.nn.Tanh: lambda x: np.tanh(x, out=x),
}


class NumpyQValues:
    """``q(obs) -> Q(obs, .)`` of a DQN-style ``QNetwork``, a batch of observations in, one row per observation out."""

    def __init__(self, q_net: Any, observation_space: spaces.Space) -> None:
        self.q_net = q_net
        # each Linear's parameter dict and the weight and bias it held when mirrored (read without nn.Module's lookup)
        self.linears = [(m._parameters, m.weight, m.bias) for m in q_net.q_net if isinstance(m, th.nn.Linear)]
        self.layers: list[tuple[np.ndarray, np.ndarray] | Callable[[np.ndarray], np.ndarray]] = []
        for module in q_net.q_net:
            if isinstance(module, th.nn.Linear):
                self.layers.append((module.weight.detach().numpy().T, module.bias.detach().numpy()))
            else:
                self.layers.append(ACTIVATIONS[type(module)])
        self.discrete = isinstance(observation_space, spaces.Discrete)
        self.width = 0 if self.discrete else int(np.prod(observation_space.shape or ()))
        # one state's pass (``state_value``): each Linear's output written into a row kept for it, no array made
        linears = [layer for layer in self.layers if type(layer) is tuple]
        self._first_row = np.empty(linears[0][1].shape, dtype=np.float32)
        self._row_layers: list[tuple[Any, np.ndarray | None]] = [
            (layer, np.empty(layer[1].shape, dtype=np.float32) if type(layer) is tuple else None)
            for layer in self.layers[1:]
        ]

    def stale(self) -> bool:
        """Whether a parameter was replaced (not updated in place) since the mirror was made."""
        for parameters, weight, bias in self.linears:
            if parameters["weight"] is not weight or parameters["bias"] is not bias:
                return True
        return False

    def __call__(self, obs: Any) -> np.ndarray:
        if self.discrete:  # SB3's one-hot of the observation's value times the first layer: that layer's rows
            weight, bias = self.layers[0]  # type: ignore[misc]
            return self._rest(weight[np.asarray(obs, dtype=np.int64).reshape(-1)] + bias)
        return self._rest(np.asarray(obs, dtype=np.float32).reshape(-1, self.width), first=0)

    def state_value(self, state: int) -> float:
        """``max_a Q(state, a)`` of one state of a ``Discrete`` space: a 1-d row through the layers (``row @ weight +
        bias``, the activation), each layer's output written into a row kept for it, so no array is made."""
        weight, bias = self.layers[0]  # type: ignore[misc]
        x = np.add(weight[state], bias, out=self._first_row)
        for layer, out in self._row_layers:
            if out is None:
                layer(x)  # an activation, in place
            else:
                x = np.matmul(x, layer[0], out=out)
                x += layer[1]
        return float(x.max())

    def _rest(self, x: np.ndarray, first: int = 1) -> np.ndarray:
        for layer in self.layers[first:] if first else self.layers:
            if type(layer) is tuple:
                x = x @ layer[0]
                x += layer[1]
            else:
                x = layer(x)  # type: ignore[operator]
        return x


def q_values_fn(model: Any) -> NumpyQValues | None:
    """The numpy mirror of ``model.q_net`` when it is the common case above, else None."""
    q_net: Any = getattr(model, "q_net", None)
    space = getattr(model, "observation_space", None)
    head = getattr(q_net, "q_net", None)
    if not isinstance(getattr(q_net, "features_extractor", None), FlattenExtractor) or not isinstance(head, th.nn.Sequential):
        return None
    if not (isinstance(space, spaces.Discrete) or (isinstance(space, spaces.Box) and not is_image_space(space))):
        return None
    if any(p.device.type != "cpu" or p.dtype != th.float32 for p in q_net.parameters()):
        return None
    if not len(head) or not isinstance(head[0], th.nn.Linear):
        return None
    if not all((isinstance(m, th.nn.Linear) and m.bias is not None) or type(m) in ACTIVATIONS for m in head):
        return None
    return NumpyQValues(q_net, space)
