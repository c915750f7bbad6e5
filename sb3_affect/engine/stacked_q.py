"""
The Q-networks of many SB3 DQN models stacked along a first "seed" axis, and DQN's gradient step on all of them at once.

Each layer of SB3's ``QNetwork`` (an MLP: ``Linear`` layers with an element-wise activation between them) becomes one
weight tensor of shape ``(S, in, out)`` (each seed's ``Linear.weight`` transposed, so that the forward pass's product
reads it in its own layout: a transposed view makes the batched product about 1.4x slower at this size) and one bias
of shape ``(S, 1, out)``, and a forward pass is one batched matrix product per layer (``torch.baddbmm``) for all S
seeds. The gradient step is SB3's ``DQN.train`` per seed:

* the TD target from the target network, ``r + (1 - done) * gamma * max_a Q_target(s', a)``;
* the Huber loss (``smooth_l1_loss``, the mean over the batch) of each seed; the sum over seeds is differentiated, so
  each seed's parameters get the gradient of its own loss;
* each seed's gradient clipped to ``max_grad_norm`` over all its parameters, as ``clip_grad_norm_`` does over
  ``policy.parameters()`` (``max_norm / (norm + 1e-6)`` clamped at 1, the norm of all its gradient's entries);
* the policy's optimizer (Adam by default) over the stacked tensors: its update is element-wise and its state is per
  element, so each seed's slice gets its own optimizer's update.

The step is fused: every seed's parameters live in one ``(S, P)`` tensor (each layer's weight and bias a view of
it), the backward pass of an MLP of ReLU or Tanh layers is written out (one batched product per layer and
operand, no autograd graph), and the norm, the clipping and Adam are each one operation on the whole ``(S, P)``
gradient (Adam: ``stacked_adam``, torch's fused kernel with denormals flushed). The output layer's weight gradient is
computed in torch's layout (the upstream gradient's transpose times the layer's input, as autograd computes a
``Linear``'s) and copied transposed: with 7 actions that product is about 4x faster than the ``(in, out)`` one (36 µs
against 154 µs for 32 seeds) and equal to autograd's bit for bit; the wider layers' are faster in the stored layout.
(Its forward pass stays a 7-wide product: one padded to 8 or 16 columns is 1.5-3x faster but not equal to SB3's
``addmm``, and after 100 steps at a learning rate of 1e-2 the weights then differ by 1.8e-5 instead of 3.5e-6.)
Other activations run torch's autograd through the same views; optimizers other than plain Adam (``AdamW``,
``RMSprop``, ``SGD``, Adam with ``amsgrad``) run torch's own on the ``(S, P)`` tensor.

Per-seed settings (each model's own): ``gamma``, ``tau``, ``max_grad_norm`` and the learning rate (with Adam) are
``(S, 1)`` columns where the seeds differ. The results differ from SB3's only by floating-point summation order (a
batched product sums in another order than one network's ``addmm``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch as th
import torch.nn.functional as F
from stable_baselines3 import DQN
from torch import nn

from sb3_affect.engine.stacked_adam import adam, clip_rows

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


#: the activations whose backward the fused steps write out: the gradient by the layer's input from the gradient by its
#: output ``y``, by the kernel autograd runs (one pass, where ``grad * (1 - y * y)`` takes three)
BACKWARDS: dict[type[nn.Module], Callable[[th.Tensor, th.Tensor], th.Tensor]] = {
    nn.ReLU: lambda grad, y: th.ops.aten.threshold_backward(grad, y, 0), nn.Tanh: th.ops.aten.tanh_backward}


#: the activations the fused steps apply in place, on the fresh output of the layer's product (their backward reads the
#: output only), without a module call
IN_PLACE: dict[type[nn.Module], Callable[[th.Tensor], th.Tensor]] = {nn.ReLU: th.relu_, nn.Tanh: th.tanh_}


def _column(values: Sequence[float]) -> float | th.Tensor:
    """One number if every seed has it, else an ``(S, 1)`` column."""
    return float(values[0]) if len(set(values)) == 1 else th.tensor(values, dtype=th.float32).reshape(-1, 1)


def network_activations(net: nn.Module) -> tuple[list[nn.Module], list[nn.Linear]]:
    """The ``Linear`` layers of an SB3 MLP each followed by its parameter-free activation (``mlp_extractor``'s nets)."""
    modules = list(net)  # type: ignore[call-overload]
    linears, activations = modules[0::2], modules[1::2]
    if len(linears) != len(activations) or not all(isinstance(m, nn.Linear) for m in linears) or any(
            list(a.parameters()) or isinstance(a, nn.Linear) for a in activations):
        raise ValueError(f"train_many stacks MLPs of Linear layers each followed by an activation: got {net}")
    return activations, linears


class StackedQ:
    """
    The online and target Q-networks and the optimizer of S DQN models, stacked (see the module docstring).

    :param models: S SB3 DQN models of one architecture (their weights are copied in; ``write_back`` copies them out)
    """

    def __init__(self, models: Sequence[DQN]) -> None:
        first = models[0]
        linears, self.activations = network_layers(first.q_net)
        self.n_seeds = len(models)
        # each layer's weight as (in, out), its bias as (1, out)
        self.shapes = [shape for layer in linears for shape in (tuple(layer.weight.shape)[::-1], (1, layer.bias.shape[0]))]
        sizes = [int(np.prod(shape)) for shape in self.shapes]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).tolist()
        self.flat = self.rows([list(m.q_net.parameters()) for m in models])
        self.target_flat = self.rows([list(m.q_net_target.parameters()) for m in models])
        self.grad = th.zeros_like(self.flat)
        self.weights, self.biases = self._views(self.flat)
        self.target_weights, self.target_biases = self._views(self.target_flat)
        self.grad_weights, self.grad_biases = self._views(self.grad)
        self.backwards = [BACKWARDS.get(type(a)) for a in self.activations]
        self.fused = all(b is not None for b in self.backwards)
        self.apply = [IN_PLACE[type(a)] for a in self.activations] if self.fused else self.activations
        self.gamma = _column([m.gamma for m in models])
        self.max_grad_norm = _column([m.max_grad_norm for m in models])
        self.tau = _column([m.tau for m in models])
        policy = first.policy
        kwargs = dict(policy.optimizer_kwargs)
        self.adam = policy.optimizer_class is th.optim.Adam and not any(
            kwargs.get(key) for key in ("amsgrad", "maximize", "capturable", "differentiable", "fused"))
        self.optimizer: th.optim.Optimizer | None = None
        if self.adam:
            self.betas = tuple(kwargs.get("betas", (0.9, 0.999)))
            self.eps, self.weight_decay = float(kwargs.get("eps", 1e-8)), float(kwargs.get("weight_decay", 0.0))
            self.exp_avg, self.exp_avg_sq = th.zeros_like(self.flat), th.zeros_like(self.flat)
            self.steps = 0
        else:
            self.optimizer = policy.optimizer_class([self.flat], lr=first.lr_schedule(1), **kwargs)  # type: ignore[call-arg]
        self.learning_rate: float | th.Tensor = first.lr_schedule(1)

    def rows(self, per_model: list[list[th.Tensor]]) -> th.Tensor:
        """
        The ``(S, P)`` rows of per-parameter tensors in ``q_net.parameters()``' order and layout, one list per seed (the
        parameters, or their optimizer's moments): each weight stored transposed.
        """
        with th.no_grad():
            return th.cat([th.stack([(p[i].detach().t() if i % 2 == 0 else p[i].detach()).reshape(-1) for p in per_model])
                           for i in range(len(self.shapes))], dim=1).contiguous()

    def _torch_layout(self, i: int, row: th.Tensor) -> th.Tensor:
        """Parameter ``i``'s slice of a row as torch's ``Linear`` holds it (a weight ``(out, in)``, a bias ``(out,)``)."""
        return row.reshape(self.shapes[i]).t() if i % 2 == 0 else row.reshape(-1)

    def _views(self, flat: th.Tensor) -> tuple[list[th.Tensor], list[th.Tensor]]:
        """Each layer's weight ``(S, in, out)`` and bias ``(S, 1, out)``, views of ``flat``."""
        views = [flat[:, a:b].view(self.n_seeds, *shape) for a, b, shape in zip(self.offsets, self.offsets[1:], self.shapes)]
        return views[0::2], views[1::2]

    def parameters(self) -> list[th.Tensor]:
        """The online network's tensors in ``q_net.parameters()`` order (weight, bias per layer)."""
        return [t for pair in zip(self.weights, self.biases) for t in pair]

    @staticmethod
    def features(observations: np.ndarray | th.Tensor) -> th.Tensor:
        """SB3's preprocessing of a flat Box observation (``float()``, then flattened per sample): ``(S, B, D)``."""
        tensor = th.as_tensor(observations)
        return tensor.float().reshape(tensor.shape[0], tensor.shape[1], -1)

    def forward(self, x: th.Tensor, weights: list[th.Tensor], biases: list[th.Tensor],
                layers: list[th.Tensor] | None = None) -> th.Tensor:
        """The Q-values of ``x``; ``layers`` collects each layer's input (for the backward pass)."""
        last = len(weights) - 1
        for i, (weight, bias) in enumerate(zip(weights, biases)):
            if layers is not None:
                layers.append(x)
            x = th.baddbmm(bias, x, weight)
            if i < last:
                x = self.apply[i](x)
        return x

    def q_values(self, observations: np.ndarray | th.Tensor, target: bool = False) -> th.Tensor:
        """Q-values ``(S, B, n_actions)`` of observations ``(S, B, ...)``."""
        with th.no_grad():
            if target:
                return self.forward(self.features(observations), self.target_weights, self.target_biases)
            return self.forward(self.features(observations), self.weights, self.biases)

    def greedy(self, observations: np.ndarray) -> np.ndarray:
        """Each seed's greedy actions ``(S, B)`` (the first of tied maxima, as ``argmax``)."""
        return self.q_values(observations).argmax(dim=2).numpy()

    def set_learning_rate(self, learning_rate: float | Sequence[float]) -> None:
        """The learning rate of every seed, or one per seed."""
        rate = _column(list(learning_rate)) if isinstance(learning_rate, Sequence) else float(learning_rate)
        if self.optimizer is not None:
            if not isinstance(rate, float):
                raise ValueError(f"learning rates per seed need Adam, not {type(self.optimizer).__name__}")
            self.optimizer.param_groups[0]["lr"] = rate
        self.learning_rate = rate

    def train_step(self, observations: th.Tensor, actions: th.Tensor, next_observations: th.Tensor, dones: th.Tensor,
                   rewards: th.Tensor) -> th.Tensor:
        """
        One gradient step of every seed on its batch (``(S, B, ...)`` tensors as SB3's ``ReplayBufferSamples``, one
        per seed); returns each seed's loss ``(S,)``.
        """
        gamma = self.gamma if isinstance(self.gamma, float) else self.gamma.unsqueeze(2)
        with th.no_grad():
            next_q_values = self.forward(self.features(next_observations), self.target_weights, self.target_biases)
            next_q_values = next_q_values.max(dim=2)[0].unsqueeze(2)
            target_q_values = rewards + (1 - dones) * gamma * next_q_values
        if self.fused:
            losses = self._fused_gradient(self.features(observations), actions.long(), target_q_values)
        else:
            losses = self._autograd_gradient(self.features(observations), actions.long(), target_q_values)
        self._clip_gradients()
        self._optimizer_step()
        return losses

    def _fused_gradient(self, x: th.Tensor, actions: th.Tensor, target_q_values: th.Tensor) -> th.Tensor:
        """The gradient of each seed's Huber loss into ``self.grad``, by the written-out backward pass; the losses."""
        layers: list[th.Tensor] = []
        q_values = self.forward(x, self.weights, self.biases, layers)
        difference = th.gather(q_values, dim=2, index=actions) - target_q_values
        size = difference.abs()
        batch = difference.shape[1]
        losses = th.where(size < 1.0, 0.5 * difference * difference, size - 0.5).mean(dim=(1, 2))
        upstream = th.zeros_like(q_values).scatter_(2, actions, difference.clamp(-1.0, 1.0) / batch)
        last = len(self.weights) - 1
        for i in range(last, -1, -1):
            if i == last:  # torch's layout, (out, in), as autograd computes it: see the module docstring
                self.grad_weights[i].copy_(th.bmm(upstream.transpose(1, 2), layers[i]).transpose(1, 2))
            else:
                self.grad_weights[i].copy_(th.bmm(layers[i].transpose(1, 2), upstream))
            self.grad_biases[i].copy_(upstream.sum(dim=1, keepdim=True))
            if i > 0:
                upstream = self.backwards[i - 1](th.bmm(upstream, self.weights[i].transpose(1, 2)), layers[i])  # type: ignore[misc]
        return losses

    def _autograd_gradient(self, x: th.Tensor, actions: th.Tensor, target_q_values: th.Tensor) -> th.Tensor:
        """The gradient of each seed's Huber loss into ``self.grad``, by torch's autograd; the losses."""
        flat = self.flat.detach().requires_grad_(True)
        weights, biases = self._views(flat)
        current_q_values = th.gather(self.forward(x, weights, biases), dim=2, index=actions)
        losses = F.smooth_l1_loss(current_q_values, target_q_values, reduction="none").mean(dim=(1, 2))
        (gradient,) = th.autograd.grad(losses.sum(), flat)
        self.grad.copy_(gradient)
        return losses.detach()

    def _clip_gradients(self) -> None:
        """``clip_grad_norm_`` per seed: each seed's gradient scaled to at most ``max_grad_norm``."""
        clip_rows(self.grad, self.max_grad_norm)

    def _optimizer_step(self) -> None:
        """The policy's optimizer on the ``(S, P)`` parameters: Adam (``stacked_adam``), or torch's own."""
        with th.no_grad():
            if self.optimizer is not None:
                self.flat.grad = self.grad
                self.optimizer.step()
                return
        self.steps += 1
        adam(self.flat, self.grad, self.exp_avg, self.exp_avg_sq, self.steps, self.betas, self.eps, self.learning_rate,
             self.weight_decay)

    def update_target(self) -> None:
        """SB3's ``polyak_update`` of the target networks with ``tau``."""
        with th.no_grad():
            self.target_flat.mul_(1 - self.tau)
            if isinstance(self.tau, float):
                self.target_flat.add_(self.flat, alpha=self.tau)
            else:
                self.target_flat.addcmul_(self.flat, self.tau)

    def _optimizer_state(self, index: int) -> list[dict[str, th.Tensor]]:
        """Seed ``index``'s optimizer state per parameter, in torch's layout (each weight's moments ``(out, in)``)."""
        if self.optimizer is None:
            if not self.steps:
                return []
            state = {"step": th.tensor(float(self.steps)), "exp_avg": self.exp_avg, "exp_avg_sq": self.exp_avg_sq}
        else:
            state = self.optimizer.state.get(self.flat, {})
            if not state:
                return []
        return [{key: value.clone() if value.dim() == 0 else self._torch_layout(i, value[index, a:b]).contiguous()
                 for key, value in state.items()} for i, (a, b) in enumerate(zip(self.offsets, self.offsets[1:]))]

    def write_back(self, models: Sequence[DQN], indices: Sequence[int] | None = None) -> None:
        """Copy each seed's online and target weights and its optimizer state into its model (``indices``: those only)."""
        with th.no_grad():
            for s in range(len(models)) if indices is None else indices:
                model = models[s]
                for flat, layers in ((self.flat, list(model.q_net.parameters())),
                                     (self.target_flat, list(model.q_net_target.parameters()))):
                    for i, (a, b, param) in enumerate(zip(self.offsets, self.offsets[1:], layers)):
                        param.copy_(self._torch_layout(i, flat[s, a:b]).reshape(param.shape))
                optimizer = model.policy.optimizer
                rate = self.learning_rate
                optimizer.param_groups[0]["lr"] = rate if isinstance(rate, float) else float(rate[s, 0])
                for state, param in zip(self._optimizer_state(s), model.q_net.parameters()):
                    optimizer.state[param] = {key: value if value.dim() == 0 else value.reshape(param.shape)
                                              for key, value in state.items()}
