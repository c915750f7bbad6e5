"""
SB3's PPO for S seeds in lockstep: the actor and critic networks of S ``ActorCriticPolicy`` models (``MlpPolicy``,
discrete actions) stacked along a seed axis, their rollouts collected together and their updates taken together.

Per seed everything is SB3's (``OnPolicyAlgorithm.collect_rollouts``, ``RolloutBuffer``, ``PPO.train``), in SB3's
order:

* **random streams**: SB3 samples the actions from torch's global generator (``Categorical.sample``, one
  ``multinomial`` per VecEnv step) and shuffles the minibatches with NumPy's (``RolloutBuffer.get``); here each seed
  has a torch ``Generator`` holding the state its model's construction left (``set_random_seed`` and the weight
  initialisation) and a ``RandomState(seed)``, taking exactly those draws;
* **the rollout**: ``n_steps`` VecEnv steps, the value of a truncated episode's terminal observation added to its
  reward (``gamma * V``), then GAE (``gamma``, ``gae_lambda``) from the last values and dones;
* **the update**: ``n_epochs`` passes over minibatches of ``batch_size`` (each seed's own permutation), the advantages
  normalised per minibatch, the clipped surrogate, the value loss (clipped with ``clip_range_vf``), the entropy term,
  ``clip_grad_norm_`` to ``max_grad_norm`` over each seed's parameters and the policy's Adam (each seed's slice of the
  stacked tensors gets its own optimizer's update: Adam is element-wise);
* **bookkeeping**: ``num_timesteps``, ``_n_updates``, ``ep_info_buffer``, the ``train/*`` keys and ``dump_logs``
  every ``log_interval`` iterations.

The forward and backward passes of all seeds are one batched matrix product per layer (``torch.baddbmm``), the
backward pass written out for Tanh and ReLU layers (as ``stacked_q``'s, from the loss's gradient by the logits and
values as autograd takes it) and torch's autograd for other activations; the results differ from SB3's by
floating-point summation order only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.type_aliases import MaybeCallback
from stable_baselines3.common.utils import explained_variance
from torch import nn

from sb3_affect.agents.sb3_fields import ModelFields
from sb3_affect.engine.lockstep import idle
from sb3_affect.engine.seed_envs import SeedEnvs
from sb3_affect.engine.stacked_adam import adam, clip_rows
from sb3_affect.engine.stacked_q import BACKWARDS, network_activations


def _column(values: Sequence[float]) -> th.Tensor:
    return th.tensor([float(v) for v in values], dtype=th.float32)


def _stacked_layout(parameter: th.Tensor) -> th.Tensor:
    """A ``Linear`` layer's weight ``(out, in)`` as ``(in, out)`` and its bias ``(out,)`` as ``(1, out)``."""
    return parameter.detach().mT if parameter.dim() == 2 else parameter.detach().reshape(1, -1)


class StackedActorCritic:
    """
    The actor and critic of S SB3 ``ActorCriticPolicy`` models stacked, and PPO's update of all of them at once.

    Every seed's parameters are one row of an ``(S, P)`` tensor; each layer's weight is a view of it ``(S, in, out)``
    (the transpose of ``Linear``'s, so that a forward pass multiplies by it as it lies in memory: measured at S = 32,
    a forward and backward pass 8% faster on a minibatch of 64 than by a transposed view, 40% on a VecEnv step's 4) and
    its bias ``(S, 1, out)``. The gradient lands in one ``(S, P)`` tensor too (written out for Tanh and ReLU layers,
    by autograd for others), so that clipping and Adam are one operation each (``stacked_adam``).

    :param models: S SB3 PPO models of one architecture (``write_back`` copies the weights and Adam's state back)
    """

    def __init__(self, models: Sequence[PPO]) -> None:
        policies = [m.policy for m in models]
        first = policies[0]
        self.n_seeds = len(models)
        self.pi_activations, pi_linears = network_activations(first.mlp_extractor.policy_net)
        self.vf_activations, vf_linears = network_activations(first.mlp_extractor.value_net)
        per_model = [[_stacked_layout(t) for t in self._sb3_parameters(p)] for p in policies]
        self.shapes = [tuple(t.shape) for t in per_model[0]]
        self.offsets = np.concatenate([[0], np.cumsum([a * b for a, b in self.shapes])]).tolist()
        self.flat = th.cat([th.stack([p[i].reshape(-1) for p in per_model]) for i in range(len(self.shapes))],
                           dim=1).contiguous()
        self.grad = th.zeros_like(self.flat)
        self.tensors = [view.requires_grad_(True) for view in self._views(self.flat)]
        self.grads = self._views(self.grad)
        self.pi_backwards = [BACKWARDS.get(type(a)) for a in self.pi_activations]
        self.vf_backwards = [BACKWARDS.get(type(a)) for a in self.vf_activations]
        self.written = all(b is not None for b in (*self.pi_backwards, *self.vf_backwards))
        layers = list(zip(self.tensors[0::2], self.tensors[1::2]))
        self.pi, self.vf = layers[:len(pi_linears)], layers[len(pi_linears):len(pi_linears) + len(vf_linears)]
        self.action, self.value = layers[-2], layers[-1]
        kwargs = dict(first.optimizer_kwargs)
        if first.optimizer_class is not th.optim.Adam or set(kwargs) - {"eps", "betas"}:
            raise ValueError(f"optimizer_class={first.optimizer_class.__name__} with {kwargs}: train_many's PPO runs "
                             "Adam with eps and betas only")
        self.betas, self.eps = tuple(kwargs.get("betas", (0.9, 0.999))), float(kwargs.get("eps", 1e-8))
        self.learning_rate = float(models[0].lr_schedule(1))
        self.exp_avg, self.exp_avg_sq = th.zeros_like(self.flat), th.zeros_like(self.flat)
        self.steps = 0

    def _views(self, flat: th.Tensor) -> list[th.Tensor]:
        """Each tensor of the layout, a view ``(S, ...)`` of ``flat`` (the parameters, their gradient or a moment)."""
        return [flat[:, a:b].view(self.n_seeds, *shape) for a, b, shape in zip(self.offsets, self.offsets[1:], self.shapes)]

    @staticmethod
    def _sb3_parameters(policy: Any) -> list[th.Tensor]:
        """A policy's tensors in ``policy.parameters()`` order (policy net, value net, action head, value head)."""
        linears = [*network_activations(policy.mlp_extractor.policy_net)[1],
                   *network_activations(policy.mlp_extractor.value_net)[1], policy.action_net, policy.value_net]
        return [t for layer in linears for t in (layer.weight, layer.bias)]

    @staticmethod
    def _mlp(x: th.Tensor, layers: list[tuple[th.Tensor, th.Tensor]], activations: list[nn.Module],
             kept: list[th.Tensor] | None) -> th.Tensor:
        for (weight, bias), activation in zip(layers, activations):
            if kept is not None:
                kept.append(x)
            x = activation(th.baddbmm(bias, x, weight))
        if kept is not None:
            kept.append(x)
        return x

    def forward(self, observations: np.ndarray | th.Tensor,
                kept: tuple[list[th.Tensor], list[th.Tensor]] | None = None) -> tuple[th.Tensor, th.Tensor]:
        """
        Each seed's action log-probabilities ``(S, B, n)`` and values ``(S, B)`` of observations ``(S, B, ...)``;
        ``kept``: the actor's and the critic's lists, to which each layer's input and the last layer's output go.
        """
        tensor = th.as_tensor(observations)
        x = tensor.float().reshape(tensor.shape[0], tensor.shape[1], -1)
        latent_pi = self._mlp(x, self.pi, self.pi_activations, None if kept is None else kept[0])
        latent_vf = self._mlp(x, self.vf, self.vf_activations, None if kept is None else kept[1])
        logits = th.baddbmm(self.action[1], latent_pi, self.action[0])
        values = th.baddbmm(self.value[1], latent_vf, self.value[0])
        return logits - logits.logsumexp(dim=-1, keepdim=True), values.squeeze(2)

    def values(self, observations: np.ndarray | th.Tensor) -> th.Tensor:
        with th.no_grad():
            return self.forward(observations)[1]

    def update(self, buffer: StackedRollout, rngs: Sequence[np.random.RandomState], settings: dict[str, th.Tensor],
               n_epochs: int, batch_size: int, normalize_advantage: bool) -> dict[str, Any]:
        """
        ``PPO.train`` of every seed on its rollout: ``n_epochs`` passes over minibatches from each seed's permutation;
        returns each seed's logged values (``(S,)`` arrays) as ``PPO.train`` logs them.
        """
        clip, clip_vf = settings["clip_range"], settings.get("clip_range_vf")
        ent_coef, vf_coef, max_grad_norm = settings["ent_coef"], settings["vf_coef"], settings["max_grad_norm"]
        total = buffer.rows * buffer.n_envs
        sums: dict[str, list[th.Tensor]] = {"entropy_loss": [], "policy_gradient_loss": [], "value_loss": [],
                                            "clip_fraction": []}
        approx_kl: list[th.Tensor] = []
        loss = th.zeros(self.n_seeds)
        samples = buffer.samples()
        for _ in range(n_epochs):
            approx_kl = []
            permutations = np.stack([rng.permutation(total) for rng in rngs])
            for start in range(0, total, batch_size):
                observations, actions, old_values, old_log_prob, advantages, returns = samples.batch(
                    permutations[:, start:start + batch_size])
                kept: tuple[list[th.Tensor], list[th.Tensor]] | None = ([], []) if self.written else None
                with th.set_grad_enabled(not self.written):
                    log_probs, values = self.forward(observations, kept)
                    log_prob = log_probs.gather(2, actions.unsqueeze(2)).squeeze(2)
                    entropy = -(log_probs.clamp(min=th.finfo(log_probs.dtype).min) * log_probs.exp()).sum(dim=2)
                    if normalize_advantage and advantages.shape[1] > 1:
                        advantages = (advantages - advantages.mean(dim=1, keepdim=True)) / (
                            advantages.std(dim=1, keepdim=True) + 1e-8)
                    ratio = th.exp(log_prob - old_log_prob)
                    column = clip.unsqueeze(1)
                    clipped = advantages * th.clamp(ratio, 1 - column, 1 + column)
                    policy_loss = -th.min(advantages * ratio, clipped).mean(dim=1)
                    limit = None if clip_vf is None else clip_vf.unsqueeze(1)
                    values_pred = values if limit is None else old_values + th.clamp(values - old_values, -limit, limit)
                    value_loss = F.mse_loss(returns, values_pred, reduction="none").mean(dim=1)
                    entropy_loss = -entropy.mean(dim=1)
                    loss = policy_loss + ent_coef * entropy_loss + vf_coef * value_loss
                with th.no_grad():
                    sums["policy_gradient_loss"].append(policy_loss.detach())
                    sums["value_loss"].append(value_loss.detach())
                    sums["entropy_loss"].append(entropy_loss.detach())
                    sums["clip_fraction"].append(((ratio - 1).abs() > column).float().mean(dim=1))
                    log_ratio = log_prob - old_log_prob
                    approx_kl.append(((th.exp(log_ratio) - 1) - log_ratio).mean(dim=1))
                if kept is None:
                    gradients = th.autograd.grad(loss.sum(), self.tensors)
                    with th.no_grad():
                        th.cat([g.reshape(self.n_seeds, -1) for g in gradients], dim=1, out=self.grad)
                else:
                    with th.no_grad():
                        logits_grad = self._logits_gradient(log_probs, actions, ratio, advantages, clipped, column,
                                                            ent_coef)
                        inside = None if limit is None else (values - old_values).abs() <= limit
                        values_grad = self._values_gradient(values_pred, returns, inside, vf_coef)
                        self._written_gradient(kept, logits_grad, values_grad)
                clip_rows(self.grad, max_grad_norm.reshape(-1, 1))
                self.steps += 1
                adam(self.flat, self.grad, self.exp_avg, self.exp_avg_sq, self.steps, self.betas, self.eps,
                     self.learning_rate)
        logs = {key: th.stack(values).double().mean(dim=0).numpy() for key, values in sums.items()}
        logs["approx_kl"] = th.stack(approx_kl).double().mean(dim=0).numpy()
        logs["loss"] = loss.detach().numpy()
        return logs

    @staticmethod
    def _logits_gradient(log_probs: th.Tensor, actions: th.Tensor, ratio: th.Tensor, advantages: th.Tensor,
                         clipped: th.Tensor, column: th.Tensor, ent_coef: th.Tensor) -> th.Tensor:
        """
        The gradient of each seed's loss by its logits ``(S, B, n)``, as autograd takes it: the clipped surrogate's
        through ``min`` (half to each side of a tie) and ``clamp`` (passing inside its closed range), the entropy
        term's, then the backward of ``logits - logsumexp(logits)``.
        """
        size = log_probs.shape[1]
        unclipped = advantages * ratio
        tie = (unclipped == clipped) * 0.5
        inside = (ratio >= 1 - column) & (ratio <= 1 + column)
        share = (unclipped < clipped) + tie + ((clipped < unclipped) + tie) * inside
        log_prob_grad = (-advantages / size) * share * ratio
        probabilities = log_probs.exp()
        grad = probabilities * (1 + log_probs.clamp(min=th.finfo(log_probs.dtype).min)) * (ent_coef / size).reshape(-1, 1, 1)
        grad.scatter_add_(2, actions.unsqueeze(2), log_prob_grad.unsqueeze(2))
        return grad - probabilities * grad.sum(dim=2, keepdim=True)

    @staticmethod
    def _values_gradient(values_pred: th.Tensor, returns: th.Tensor, inside: th.Tensor | None, vf_coef: th.Tensor
                         ) -> th.Tensor:
        """The gradient of each seed's loss by its values ``(S, B, 1)`` (``inside``: where ``clip_range_vf`` passes it)."""
        grad = (values_pred - returns) * (2 * vf_coef / values_pred.shape[1]).unsqueeze(1)
        return (grad if inside is None else grad * inside).unsqueeze(2)

    def _written_gradient(self, kept: tuple[list[th.Tensor], list[th.Tensor]], logits_grad: th.Tensor,
                          values_grad: th.Tensor) -> None:
        """
        The backward pass of the actor and the critic written out (Tanh or ReLU layers: ``BACKWARDS``) from their layers'
        inputs ``kept`` by ``forward``: per layer one batched product for the weight's gradient and one sum for the
        bias's, each written into its view of ``self.grad``, and one product for the input's (but the first layer's).
        """
        n_pi, n_vf = len(self.pi), len(self.vf)
        heads = 2 * (n_pi + n_vf)
        for layers, backwards, inputs, upstream, indices in (
                ([*self.pi, self.action], self.pi_backwards, kept[0], logits_grad, [*range(0, 2 * n_pi, 2), heads]),
                ([*self.vf, self.value], self.vf_backwards, kept[1], values_grad, [*range(2 * n_pi, heads, 2), heads + 2])):
            for i in range(len(layers) - 1, -1, -1):
                th.bmm(inputs[i].mT, upstream, out=self.grads[indices[i]])
                th.sum(upstream, dim=1, keepdim=True, out=self.grads[indices[i] + 1])
                if i:
                    upstream = backwards[i - 1](th.bmm(upstream, layers[i][0].mT), inputs[i])  # type: ignore[misc]

    def set_learning_rate(self, learning_rate: float) -> None:
        self.learning_rate = float(learning_rate)

    def write_back(self, models: Sequence[PPO], indices: Sequence[int] | None = None) -> None:
        """Copy each seed's weights and Adam state into its model's policy (``indices``: those only)."""
        with th.no_grad():
            for s in range(len(models)) if indices is None else indices:
                policy = models[s].policy
                for stacked, m, v, param in zip(self.tensors, self._views(self.exp_avg), self._views(self.exp_avg_sq),
                                                self._sb3_parameters(policy)):
                    param.copy_(stacked[s].mT.reshape(param.shape))
                    if self.steps:
                        policy.optimizer.state[param] = {"step": th.tensor(float(self.steps)),
                                                         "exp_avg": m[s].mT.reshape(param.shape).clone(),
                                                         "exp_avg_sq": v[s].mT.reshape(param.shape).clone()}
                policy.optimizer.param_groups[0]["lr"] = self.learning_rate


class StackedRollout:
    """
    The rollout buffers of S seeds in one set of arrays ``(S, n_steps, E)``, SB3's ``RolloutBuffer`` per seed (its
    arrays, GAE and minibatches); ``release`` writes each seed's rollout into its model's buffer.

    :param obs_dtype: the observations' array: SB3's float32, or ``uint8`` for ``uint8`` observations (the same
        numbers, a quarter of the bytes for the minibatches' gathers to read)
    """

    def __init__(self, n_seeds: int, rows: int, n_envs: int, obs_shape: tuple[int, ...],
                 obs_dtype: type[np.floating] | type[np.uint8] = np.float32) -> None:
        self.rows, self.n_envs = rows, n_envs
        self.observations = np.zeros((n_seeds, rows, n_envs, *obs_shape), dtype=obs_dtype)
        self.actions = np.zeros((n_seeds, rows, n_envs), dtype=np.int64)
        self.rewards, self.episode_starts, self.values, self.log_probs, self.advantages, self.returns = (
            np.zeros((n_seeds, rows, n_envs), dtype=np.float32) for _ in range(6))
        self.pos = 0

    def add(self, obs: np.ndarray, actions: np.ndarray, rewards: np.ndarray, episode_starts: np.ndarray,
            values: th.Tensor, log_probs: th.Tensor) -> None:
        pos = self.pos
        self.observations[:, pos] = obs
        self.actions[:, pos] = actions
        self.rewards[:, pos] = rewards
        self.episode_starts[:, pos] = episode_starts
        self.values[:, pos] = values.numpy()
        self.log_probs[:, pos] = log_probs.numpy()
        self.pos += 1

    def compute_returns_and_advantage(self, last_values: th.Tensor, dones: np.ndarray, gamma: np.ndarray,
                                      gae_lambda: np.ndarray) -> None:
        """SB3's GAE, every seed at once (``gamma`` and ``gae_lambda`` float32 columns ``(S, 1)``)."""
        last = last_values.numpy()
        gae = np.zeros_like(last)
        for step in reversed(range(self.rows)):
            if step == self.rows - 1:
                next_non_terminal, next_values = 1.0 - dones.astype(np.float32), last
            else:
                next_non_terminal, next_values = 1.0 - self.episode_starts[:, step + 1], self.values[:, step + 1]
            delta = self.rewards[:, step] + gamma * next_values * next_non_terminal - self.values[:, step]
            gae = delta + gamma * gae_lambda * next_non_terminal * gae
            self.advantages[:, step] = gae
        self.returns = self.advantages + self.values

    def samples(self) -> RolloutSamples:
        """Every seed's arrays as ``RolloutBuffer.get`` reads them (``swap_and_flatten``: env-major), for minibatches."""
        scalars = np.stack([self.actions.astype(np.float32), self.values, self.log_probs, self.advantages, self.returns],
                           axis=-1)
        observations, columns = (th.as_tensor(np.ascontiguousarray(array.swapaxes(1, 2))).reshape(-1, *array.shape[3:])
                                 for array in (self.observations, scalars))
        return RolloutSamples(observations, columns, self.rows * self.n_envs)

    def release(self, models: Sequence[PPO], indices: Sequence[int]) -> None:
        """
        Write seeds ``indices``' rollout into their models' ``RolloutBuffer``, as SB3's holds it after ``train`` (the
        arrays its minibatches read swapped and flattened to ``(E * n_steps, ...)``, env-major).
        """
        for s in indices:
            buffer: Any = models[s].rollout_buffer
            for name in ("rewards", "episode_starts"):
                setattr(buffer, name, getattr(self, name)[s].copy())
            for name in ("observations", "actions", "values", "log_probs", "advantages", "returns"):
                array = getattr(self, name)[s].swapaxes(0, 1)
                shape = (self.n_envs * self.rows, *(array.shape[2:] or (1,)))  # SB3's swap_and_flatten
                setattr(buffer, name, array.reshape(shape).astype(np.float32))
            buffer.pos, buffer.full, buffer.generator_ready = self.rows, True, True


class RolloutSamples:
    """
    The rollout of S seeds flattened for minibatches: the observations ``(S * N, ...)`` and the actions, values, log
    probabilities, advantages and returns ``(S * N, 5)``, each seed's ``N`` rows in ``swap_and_flatten``'s order.
    """

    def __init__(self, observations: th.Tensor, columns: th.Tensor, rows: int) -> None:
        self.observations, self.columns, self.rows = observations, columns, rows

    def batch(self, indices: np.ndarray) -> tuple[th.Tensor, ...]:
        """Each seed's minibatch of flat indices ``(S, B)`` into its rows: the observations, actions, values, log
        probabilities, advantages and returns, ``(S, B, ...)`` each."""
        n_seeds, size = indices.shape
        rows = th.as_tensor((indices + self.rows * np.arange(n_seeds)[:, None]).reshape(-1))
        observations = self.observations.index_select(0, rows).view(n_seeds, size, *self.observations.shape[1:])
        actions, values, log_probs, advantages, returns = self.columns.index_select(0, rows).view(n_seeds, size, 5).unbind(2)
        return observations, actions.long(), values, log_probs, advantages, returns


class LockstepPPO:
    """
    SB3's ``PPO.learn`` of S models in lockstep (see the module docstring).

    :param models: the models, one per seed, of one class and one set of lockstep arguments, each with its VecEnv
    :param seeds: their seeds
    :param generators: each seed's torch generator state after its model was built (what SB3's sampling draws from)
    """

    #: set by ``learn``
    obs: np.ndarray
    episode_starts: np.ndarray
    stack: StackedActorCritic
    rollout: StackedRollout

    def __init__(self, models: Sequence[PPO], seeds: Sequence[int], generators: Sequence[th.Tensor]) -> None:
        self.models = list(models)
        self.fields = [ModelFields(m) for m in self.models]
        self.rngs = [np.random.RandomState(seed) for seed in seeds]
        self.generators = []
        for state in generators:
            generator = th.Generator()
            generator.set_state(state)
            self.generators.append(generator)
        first = self.models[0]
        if not isinstance(first.action_space, spaces.Discrete):
            raise ValueError(f"action_space={first.action_space}: train_many's PPO stacks discrete actions only")
        self.n_seeds, self.n_envs, self.n_actions = len(self.models), first.n_envs, int(first.action_space.n)
        self.envs = SeedEnvs([m.get_env() for m in self.models])  # type: ignore[misc]
        self.frozen = np.zeros(self.n_seeds, dtype=bool)
        self.gamma = np.array([[m.gamma] for m in self.models], dtype=np.float32)
        self.gae_lambda = np.array([[m.gae_lambda] for m in self.models], dtype=np.float32)

    def _live(self) -> list[int]:
        return np.flatnonzero(~self.frozen).tolist()

    def _draws(self, n_steps: int) -> th.Tensor:
        """
        Each seed's exponential draws for the ``n_steps`` steps of a rollout, ``(S, n_steps, E, n_actions)``, from its
        own generator: one call per seed, not per step, drawing the numbers one draw per step would, in their order
        (torch's CPU ``exponential_`` fills a tensor one element after the other from the generator).
        """
        draws = th.empty((self.n_seeds, n_steps, self.n_envs, self.n_actions))
        for draw, generator in zip(draws, self.generators):
            draw.exponential_(1, generator=generator)
        return draws

    @staticmethod
    def _sample(log_probs: th.Tensor, draws: th.Tensor) -> th.Tensor:
        """
        Each seed's ``Categorical.sample()``: ``(S, E)``. For one sample torch's ``multinomial`` is ``argmax(p / q)``
        with ``q`` exponential draws of ``p``'s shape (the step's ``draws``, each seed's from its generator); the division
        and argmax are one operation for all seeds.
        """
        return (log_probs.exp() / draws).argmax(dim=-1)

    def _settings(self, progress: float) -> dict[str, th.Tensor]:
        models = self.models
        settings = {"clip_range": _column([m.clip_range(progress) for m in models]),  # type: ignore[operator]
                    "ent_coef": _column([m.ent_coef for m in models]), "vf_coef": _column([m.vf_coef for m in models]),
                    "max_grad_norm": _column([m.max_grad_norm for m in models])}
        if models[0].clip_range_vf is not None:
            settings["clip_range_vf"] = _column([m.clip_range_vf(progress) for m in models])  # type: ignore[misc,operator]
        return settings

    def _freeze(self, index: int, callback: BaseCallback) -> None:
        self.frozen[index] = True
        self.stack.write_back(self.models, [index])
        self._hand_back(index)
        callback.on_training_end()

    def _hand_back(self, index: int) -> None:
        """Seed ``index``'s current observation and episode starts into its model, where ``learn`` leaves them."""
        fields = self.fields[index]
        fields.last_obs, fields.last_episode_starts = self.obs[index], self.episode_starts[index]

    def _collect(self, callbacks: dict[int, BaseCallback], n_steps: int) -> None:
        """``collect_rollouts`` of every live seed (``n_steps`` VecEnv steps, then GAE)."""
        models = self.models
        for index in self._live():
            if models[index].policy.training:  # set once: nothing here sets it back (each call walks the modules)
                models[index].policy.set_training_mode(False)
        self.rollout.pos = 0
        for callback in callbacks.values():
            callback.on_rollout_start()
        dones = np.zeros((self.n_seeds, self.n_envs), dtype=bool)
        draws = self._draws(n_steps)
        while self.rollout.pos < n_steps:
            with th.no_grad():
                log_probs, values = self.stack.forward(self.obs)
                actions = self._sample(log_probs, draws[:, self.rollout.pos])
                chosen = log_probs.gather(2, actions.unsqueeze(2)).squeeze(2)
            action_array = actions.numpy()
            new_obs, rewards, dones, infos = self.envs.step(action_array, all_infos=bool(callbacks))
            live = self._live()
            for index in live:
                models[index].num_timesteps += self.n_envs
            for index, callback in list(callbacks.items()):
                model = models[index]
                callback.update_locals({"self": model, "actions": action_array[index], "new_obs": new_obs[index],
                                        "rewards": rewards[index], "dones": dones[index], "infos": infos[index],
                                        "env": model.env, "values": values[index], "log_probs": chosen[index]})
                if not callback.on_step():
                    del callbacks[index]
                    self._freeze(index, callback)
            if self.on_models is not None and self.every:
                timesteps = models[self._live()[0]].num_timesteps if not self.frozen.all() else 0
                if timesteps // self.every > (timesteps - self.n_envs) // self.every:
                    self.stack.write_back(models, self._live())
                    self.on_models(models)
            for index in np.flatnonzero(dones.any(axis=1) & ~self.frozen).tolist():
                self.fields[index].update_info_buffer(infos[index], dones[index])
            rewards = rewards.astype(np.float32, copy=True)
            truncated = [(s, e) for s, e in zip(*np.nonzero(dones))
                         if infos[s][e].get("terminal_observation") is not None
                         and infos[s][e].get("TimeLimit.truncated", False)]
            if truncated:
                terminal = np.stack([infos[s][e]["terminal_observation"] for s, e in truncated])
                with th.no_grad():
                    for (s, e), obs in zip(truncated, terminal):
                        value = self._value(s, obs)
                        rewards[s, e] += models[s].gamma * value
            self.rollout.add(self.obs, action_array, rewards, self.episode_starts, values, chosen)
            self.obs, self.episode_starts = new_obs, dones.astype(np.float32)
            if self.frozen.all():
                return
        last_values = self.stack.values(self.obs)
        self.rollout.compute_returns_and_advantage(last_values, dones, self.gamma, self.gae_lambda)
        for callback in callbacks.values():
            callback.on_rollout_end()

    def _value(self, seed: int, observation: np.ndarray) -> th.Tensor:
        """Seed ``seed``'s ``predict_values`` of one observation (a truncated episode's terminal one)."""
        batch = th.as_tensor(observation).float().reshape(1, 1, -1)
        x = batch
        for (weight, bias), activation in zip(self.stack.vf, self.stack.vf_activations):
            x = activation(th.baddbmm(bias[seed:seed + 1], x, weight[seed:seed + 1]))
        weight, bias = self.stack.value
        return th.baddbmm(bias[seed:seed + 1], x, weight[seed:seed + 1])[0, 0, 0]

    def _train(self) -> None:
        """``PPO.train`` of every live seed, on its rollout."""
        live = self._live()
        models, first = self.models, self.models[live[0]]
        progress = self.fields[live[0]].progress
        rates = {m.lr_schedule(progress) for m in models}
        if len(rates) != 1:
            raise ValueError("learning_rate per seed: train_many's PPO takes one learning rate for all seeds")
        rate = rates.pop()
        self.stack.set_learning_rate(rate)
        settings = self._settings(progress)
        logs = self.stack.update(self.rollout, self.rngs, settings, first.n_epochs, first.batch_size,
                                 first.normalize_advantage)
        for index in live:
            fields = self.fields[index]
            fields.n_updates += first.n_epochs
            logger = models[index].logger
            logger.record("train/learning_rate", rate)
            for key in ("entropy_loss", "policy_gradient_loss", "value_loss", "approx_kl", "clip_fraction", "loss"):
                logger.record(f"train/{key}", float(logs[key][index]))
            logger.record("train/explained_variance", float(explained_variance(
                self.rollout.values[index].T.flatten(), self.rollout.returns[index].T.flatten())))
            logger.record("train/n_updates", fields.n_updates, exclude="tensorboard")
            logger.record("train/clip_range", float(settings["clip_range"][index]))
            if "clip_range_vf" in settings:
                logger.record("train/clip_range_vf", float(settings["clip_range_vf"][index]))

    def learn(self, total_timesteps: int, log_interval: int = 1, every: int = 0,
              on_models: Callable[[list[PPO]], object] | None = None,
              user_callbacks: Sequence[MaybeCallback] | None = None) -> list[PPO]:
        """``model.learn(total_timesteps, callback=user_callbacks[i], log_interval=log_interval)`` of every model."""
        models = self.models
        self.every, self.on_models = every, on_models
        callbacks: dict[int, BaseCallback] = {}
        total = total_timesteps
        for index, (model, given) in enumerate(zip(models, user_callbacks or [None] * len(models))):
            total, callback = self.fields[index].setup_learn(total_timesteps, given, "PPO")
            callback.on_training_start({"self": model, "total_timesteps": total, "callback": callback,
                                        "log_interval": log_interval}, globals())
            if not idle(callback):
                callbacks[index] = callback
        self.obs = np.stack([fields.last_obs for fields in self.fields])
        self.episode_starts = np.stack([fields.last_episode_starts for fields in self.fields]).astype(np.float32)
        self.stack = StackedActorCritic(models)
        first = models[0]
        self.rollout = StackedRollout(self.n_seeds, first.n_steps, self.n_envs, first.observation_space.shape or (),
                                      np.uint8 if first.observation_space.dtype == np.uint8 else np.float32)
        iteration = 0
        try:
            while not self.frozen.all() and models[self._live()[0]].num_timesteps < total:
                self._collect(callbacks, first.n_steps)
                if self.frozen.all():
                    break
                iteration += 1
                for index in self._live():
                    model = models[index]
                    self.fields[index].update_progress(model.num_timesteps, total)
                    if log_interval is not None and iteration % log_interval == 0:
                        model.dump_logs(iteration)
                self._train()
            for index in self._live():
                if index in callbacks:
                    callbacks[index].on_training_end()
        finally:
            live = self._live()
            self.stack.write_back(models, live)
            self.rollout.release(models, live)
            for index in live:
                self._hand_back(index)
        return models
