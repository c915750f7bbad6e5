"""
The Q-networks of many SB3 DQN models stacked along a first "seed" axis, and DQN's gradient step on all of them at once.

Each layer of SB3's ``QNetwork`` (an MLP: ``Linear`` layers with an element-wise activation between them) becomes one
weight tensor of shape ``(S, out, in)`` and one bias of shape ``(S, 1, out)``, and a forward pass is one batched matrix
product per layer (``torch.baddbmm``) for all S seeds. The gradient step is SB3's ``DQN.train`` per seed:

* the TD target from the target network, ``r + (1 - done) * gamma * max_a Q_target(s', a)``;
* the Huber loss (``smooth_l1_loss``, the mean over the batch) of each seed; the sum over seeds is differentiated, so
  each seed's parameters get the gradient of its own loss;
* each seed's gradient clipped to ``max_grad_norm`` over all its parameters, as ``clip_grad_norm_`` does over
  ``policy.parameters()`` (the norm of the per-parameter norms, ``max_norm / (norm + 1e-6)`` clamped at 1);
* the policy's optimizer (Adam by default) over the stacked tensors: its update is element-wise and its state is per
  element, so each seed's slice gets exactly its own optimizer's update (run ``foreach``, which computes what the
  per-tensor loop computes, bit for bit, unless the policy's ``optimizer_kwargs`` choose ``foreach`` or ``fused``).

The results differ from SB3's only by floating-point summation order (a batched product sums in another order than
one network's ``addmm``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch as th
import torch.nn.functional as F
from stable_baselines3 import DQN
from torch import nn

#: optimizers whose update is element-wise, so stacking the seeds changes nothing
ELEMENTWISE_OPTIMIZERS = (th.optim.Adam, th.optim.AdamW, th.optim.RMSprop, th.optim.SGD)


def network_layers(q_net: nn.Module) -> tuple[list[nn.Linear], list[nn.Module]]:
    """The ``Linear`` layers of an SB3 ``QNetwork``'s MLP and the parameter-free activations after each but the last."""
    linears: list[nn.Linear] = []
    activations: list[nn.Module] = []
    for module in q_net.q_net:  # type: ignore[union-attr]
        if isinstance(module, nn.Linear):
            linears.append(module)
        elif type(module).__module__ == nn.modules.activation.__name__ and not list(module.parameters()):
            activations.append(module)
        else:
            raise ValueError(f"train_many stacks MLP Q-networks (Linear layers, activations): got {type(module).__name__}")
    if len(activations) != len(linears) - 1:
        raise ValueError("train_many stacks MLP Q-networks with one activation between Linear layers")
    return linears, activations


class StackedQ:
    """
    The online and target Q-networks and the optimizer of S DQN models, stacked (see the module docstring).

    :param models: S SB3 DQN models of one architecture (their weights are copied in; ``write_back`` copies them out)
    """

    def __init__(self, models: Sequence[DQN]) -> None:
        first = models[0]
        linears, self.activations = network_layers(first.q_net)
        self.n_seeds = len(models)
        per_model = [network_layers(m.q_net)[0] for m in models]
        per_target = [network_layers(m.q_net_target)[0] for m in models]
        self.weights = [th.stack([layers[i].weight.detach() for layers in per_model]).clone() for i in range(len(linears))]
        self.biases = [th.stack([layers[i].bias.detach() for layers in per_model]).unsqueeze(1).clone()
                       for i in range(len(linears))]
        self.target_weights = [th.stack([layers[i].weight.detach() for layers in per_target]).clone()
                               for i in range(len(linears))]
        self.target_biases = [th.stack([layers[i].bias.detach() for layers in per_target]).unsqueeze(1).clone()
                              for i in range(len(linears))]
        for tensor in self.parameters():
            tensor.requires_grad_(True)
        policy = first.policy
        kwargs = dict(policy.optimizer_kwargs)
        if not {"foreach", "fused"} & kwargs.keys():
            kwargs["foreach"] = True  # the same arithmetic as SB3's per-tensor loop, bit for bit, in fewer calls
        self.optimizer: th.optim.Optimizer = policy.optimizer_class(  # type: ignore[call-arg]
            self.parameters(), lr=first.lr_schedule(1), **kwargs)
        self.gamma, self.max_grad_norm, self.tau = float(first.gamma), float(first.max_grad_norm), float(first.tau)

    def parameters(self) -> list[th.Tensor]:
        """The online network's tensors in ``q_net.parameters()`` order (weight, bias per layer)."""
        return [t for pair in zip(self.weights, self.biases) for t in pair]

    def _targets(self) -> list[th.Tensor]:
        return [t for pair in zip(self.target_weights, self.target_biases) for t in pair]

    @staticmethod
    def features(observations: np.ndarray | th.Tensor) -> th.Tensor:
        """SB3's preprocessing of a flat Box observation (``float()``, then flattened per sample): ``(S, B, D)``."""
        tensor = th.as_tensor(observations)
        return tensor.float().reshape(tensor.shape[0], tensor.shape[1], -1)

    def _forward(self, x: th.Tensor, weights: list[th.Tensor], biases: list[th.Tensor]) -> th.Tensor:
        last = len(weights) - 1
        for i, (weight, bias) in enumerate(zip(weights, biases)):
            x = th.baddbmm(bias, x, weight.transpose(1, 2))
            if i < last:
                x = self.activations[i](x)
        return x

    def q_values(self, observations: np.ndarray | th.Tensor, target: bool = False) -> th.Tensor:
        """Q-values ``(S, B, n_actions)`` of observations ``(S, B, ...)``."""
        with th.no_grad():
            if target:
                return self._forward(self.features(observations), self.target_weights, self.target_biases)
            return self._forward(self.features(observations), self.weights, self.biases)

    def greedy(self, observations: np.ndarray) -> np.ndarray:
        """Each seed's greedy actions ``(S, B)`` (the first of tied maxima, as ``argmax``)."""
        return self.q_values(observations).argmax(dim=2).numpy()

    def set_learning_rate(self, learning_rate: float) -> None:
        for group in self.optimizer.param_groups:
            group["lr"] = learning_rate

    def train_step(self, observations: th.Tensor, actions: th.Tensor, next_observations: th.Tensor, dones: th.Tensor,
                   rewards: th.Tensor) -> th.Tensor:
        """
        One gradient step of every seed on its batch (``(S, B, ...)`` tensors as SB3's ``ReplayBufferSamples``, one
        per seed); returns each seed's loss ``(S,)``.
        """
        with th.no_grad():
            next_q_values = self._forward(self.features(next_observations), self.target_weights, self.target_biases)
            next_q_values = next_q_values.max(dim=2)[0].unsqueeze(2)
            target_q_values = rewards + (1 - dones) * self.gamma * next_q_values
        current_q_values = self._forward(self.features(observations), self.weights, self.biases)
        current_q_values = th.gather(current_q_values, dim=2, index=actions.long())
        losses = F.smooth_l1_loss(current_q_values, target_q_values, reduction="none").mean(dim=(1, 2))
        self.optimizer.zero_grad()
        losses.sum().backward()
        self._clip_gradients()
        self.optimizer.step()
        return losses.detach()

    def _clip_gradients(self) -> None:
        """``clip_grad_norm_`` per seed: the 2-norm of the per-parameter 2-norms, each seed's own."""
        grads = [p.grad for p in self.parameters() if p.grad is not None]  # each (S, rows, columns)
        norms = th.stack([th.linalg.vector_norm(g, 2, dim=(1, 2)) for g in grads])
        total = th.linalg.vector_norm(norms, 2, dim=0)
        coefficient = th.clamp(self.max_grad_norm / (total + 1e-6), max=1.0).reshape(-1, 1, 1)
        for g in grads:
            g.mul_(coefficient)

    def update_target(self) -> None:
        """SB3's ``polyak_update`` of the target networks with ``tau``."""
        with th.no_grad():
            targets = self._targets()
            th._foreach_mul_(targets, 1 - self.tau)
            th._foreach_add_(targets, self.parameters(), alpha=self.tau)

    def write_back(self, models: Sequence[DQN]) -> None:
        """Copy each seed's online and target weights and its optimizer state into its model."""
        with th.no_grad():
            for s, model in enumerate(models):
                for tensors, layers in ((self.parameters(), list(model.q_net.parameters())),
                                        (self._targets(), list(model.q_net_target.parameters()))):
                    for stacked, param in zip(tensors, layers):
                        param.copy_(stacked[s].reshape(param.shape))
                optimizer = model.policy.optimizer
                optimizer.param_groups[0]["lr"] = self.optimizer.param_groups[0]["lr"]
                for stacked, param in zip(self.parameters(), model.q_net.parameters()):
                    state = self.optimizer.state.get(stacked)
                    if state:
                        optimizer.state[param] = {key: value.clone() if key == "step" or value.dim() == 0
                                                  else value[s].reshape(param.shape).clone()
                                                  for key, value in state.items()}

