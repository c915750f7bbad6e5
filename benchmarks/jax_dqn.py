"""
A vmapped JAX DQN on NAVIX's Empty-8x8 (``jax``, ``navix`` and ``optax``: ``pip install "sb3-affect[jax]"``), the JAX
row of ``bench_many_seeds.py``: S seeds of SB3's DQN as ``bench_many_seeds.SETTINGS`` sets it (the MLP 147-64-64-7 with
ReLU on the 7x7x3 view as floats, Adam at ``learning_rate``, the Huber loss, gradients clipped at norm 10, gamma 0.99,
a buffer of ``buffer_size`` transitions per seed, one gradient step of ``batch_size`` every ``train_freq`` VecEnv steps
after ``learning_starts``, the target network copied every ``target_update_interval`` env steps, epsilon from 1 to
0.05 over ``exploration_fraction`` of the run), each seed on ``n_envs`` envs, the whole run one XLA program (one
``lax.scan`` over the VecEnv steps, the seeds and envs ``vmap``-ped). NAVIX's Empty-8x8 is MiniGrid's layout with
its own step (its first-person symbolic view, a step limit of 256 as Farama's 4 x 8**2); an ended episode is reset
at once, as SB3's VecEnv resets it, its last view stored as the transition's next observation.
"""

from __future__ import annotations

import os
from typing import Any

from sb3_affect.kernel.minigrid_view import VIEW_SIZE as VIEW
from sb3_affect.kernel.minigrid_world import MINIGRID_ACTIONS as ACTIONS

HIDDEN = 64  # SB3's DQN net_arch [64, 64]
EPSILON_END = 0.05


def single_thread() -> None:
    """One XLA CPU thread (as the torch rows' one torch thread); set before ``jax`` is imported."""
    os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")


def dqn_update(settings: dict[str, Any]) -> tuple[Any, Any, Any, Any]:
    """
    The DQN's network and its gradient step, as ``dqn_many`` runs them: ``(init_params, q_values, optimiser, update)``,
    ``update(params, target, opt, obs, action, reward, next_obs, terminated) -> (params, opt)`` one step of one seed on
    one batch (the target's and the online network's forward passes, the Huber loss, its gradient, clipping, Adam).
    """
    single_thread()
    import jax
    import jax.numpy as jnp
    import optax

    gamma = settings.get("gamma", 0.99)
    optimiser = optax.chain(optax.clip_by_global_norm(10.0), optax.adam(settings["learning_rate"]))

    def init_params(key: Any) -> list[tuple[Any, Any]]:
        params = []
        for key_, (fan_in, fan_out) in zip(jax.random.split(key, 3), [(VIEW, HIDDEN), (HIDDEN, HIDDEN), (HIDDEN, ACTIONS)]):
            bound = 1 / fan_in**0.5  # torch's nn.Linear initialisation
            w_key, b_key = jax.random.split(key_)
            params.append((jax.random.uniform(w_key, (fan_in, fan_out), minval=-bound, maxval=bound),
                           jax.random.uniform(b_key, (fan_out,), minval=-bound, maxval=bound)))
        return params

    def q_values(params: list[tuple[Any, Any]], views: Any) -> Any:
        x = views.astype(jnp.float32)
        for w, b in params[:-1]:
            x = jax.nn.relu(x @ w + b)
        w, b = params[-1]
        return x @ w + b

    def loss(params: Any, target: Any, obs: Any, action: Any, reward: Any, next_obs: Any, terminated: Any) -> Any:
        following = jnp.max(q_values(target, next_obs), axis=-1)
        aim = jax.lax.stop_gradient(reward + (1.0 - terminated) * gamma * following)
        chosen = jnp.take_along_axis(q_values(params, obs), action[:, None], axis=-1)[:, 0]
        return jnp.mean(optax.huber_loss(chosen, aim))

    def update(params: Any, target: Any, opt: Any, obs: Any, action: Any, reward: Any, next_obs: Any,
               terminated: Any) -> tuple[Any, Any]:
        grads = jax.grad(loss)(params, target, obs, action, reward, next_obs, terminated)
        updates, opt = optimiser.update(grads, opt, params)
        return optax.apply_updates(params, updates), opt

    return init_params, q_values, optimiser, update


def dqn_many(n_seeds: int, n_envs: int, total_timesteps: int, settings: dict[str, Any]) -> Any:
    """
    The jitted run of ``n_seeds`` DQNs (``run(seed)`` trains them from ``seed`` and returns the seeds' stacked
    ``params``, ``target``, ``opt`` (optax's state) and the ``episodes`` each ended); ``total_timesteps`` env steps per
    seed, ``settings`` SB3's DQN keyword arguments above.
    """
    single_thread()
    import jax
    import jax.numpy as jnp
    import navix as nx

    env = nx.make("Navix-Empty-8x8-v0", max_steps=256, observation_fn=nx.observations.symbolic_first_person)
    steps = total_timesteps // n_envs  # VecEnv steps
    capacity = max(settings["buffer_size"] // n_envs, 1)
    train_every, batch = settings["train_freq"], settings["batch_size"]
    starts = settings["learning_starts"] // n_envs
    target_every = max(settings["target_update_interval"] // n_envs, 1)
    explore = settings["exploration_fraction"] * total_timesteps
    init_params, q_values, optimiser, update = dqn_update(settings)

    def env_step(timestep: Any, action: Any) -> tuple[Any, Any, Any, Any]:
        """One step and SB3's reset of an ended episode: (next timestep, its view to store, reward, terminated)."""
        stepped = env._step(timestep, action)
        done = stepped.is_done()
        fresh = env.reset(stepped.state.key)
        following = jax.tree_util.tree_map(lambda new, old: jnp.where(done, new, old), fresh, stepped)
        return following, stepped.observation.reshape(VIEW), stepped.reward, stepped.is_termination()

    def init(key: Any) -> dict[str, Any]:
        p_key, e_key, s_key = jax.random.split(key, 3)
        params = init_params(p_key)
        timesteps = jax.vmap(env.reset)(jax.random.split(e_key, n_envs))
        return {"params": params, "target": params, "opt": optimiser.init(params), "timesteps": timesteps,
                "obs": jnp.zeros((capacity, n_envs, VIEW), jnp.uint8), "next": jnp.zeros((capacity, n_envs, VIEW), jnp.uint8),
                "action": jnp.zeros((capacity, n_envs), jnp.int32), "reward": jnp.zeros((capacity, n_envs), jnp.float32),
                "terminated": jnp.zeros((capacity, n_envs), jnp.float32), "key": s_key, "episodes": jnp.zeros((), jnp.int32)}

    def act(state: dict[str, Any], i: Any) -> dict[str, Any]:
        key, coin_key, random_key = jax.random.split(state["key"], 3)
        views = state["timesteps"].observation.reshape(n_envs, VIEW)
        epsilon = jnp.maximum(1.0 - (1.0 - EPSILON_END) * (i * n_envs) / explore, EPSILON_END)
        greedy = jnp.argmax(q_values(state["params"], views), axis=-1)
        random = jax.random.randint(random_key, (n_envs,), 0, ACTIONS)
        action = jnp.where(jax.random.uniform(coin_key, (n_envs,)) < epsilon, random, greedy).astype(jnp.int32)
        timesteps, next_views, reward, terminated = jax.vmap(env_step)(state["timesteps"], action)
        row = i % capacity
        return {**state, "key": key, "timesteps": timesteps, "obs": state["obs"].at[row].set(views),
                "next": state["next"].at[row].set(next_views), "action": state["action"].at[row].set(action),
                "reward": state["reward"].at[row].set(reward), "terminated": state["terminated"].at[row].set(terminated),
                "episodes": state["episodes"] + jnp.sum(timesteps.t == 0)}

    def train(state: dict[str, Any], i: Any) -> dict[str, Any]:
        key, row_key, env_key = jax.random.split(state["key"], 3)
        rows = jax.random.randint(row_key, (batch,), 0, jnp.minimum(i + 1, capacity))
        envs = jax.random.randint(env_key, (batch,), 0, n_envs)
        sample = [state[name][rows, envs] for name in ("obs", "action", "reward", "next", "terminated")]
        params, opt = update(state["params"], state["target"], state["opt"], *sample)
        return {**state, "key": key, "params": params, "opt": opt}

    def vec_step(states: dict[str, Any], i: Any) -> tuple[dict[str, Any], None]:
        states = jax.vmap(act, in_axes=(0, None))(states, i)
        states = jax.lax.cond((i >= starts) & ((i + 1) % train_every == 0),
                              lambda s: jax.vmap(train, in_axes=(0, None))(s, i), lambda s: s, states)
        states = jax.lax.cond((i + 1) % target_every == 0, lambda s: {**s, "target": s["params"]}, lambda s: s, states)
        return states, None

    @jax.jit
    def run(seed: Any) -> dict[str, Any]:
        states = jax.vmap(init)(jax.random.split(jax.random.PRNGKey(seed), n_seeds))
        states, _ = jax.lax.scan(vec_step, states, jnp.arange(steps))
        return {name: states[name] for name in ("params", "target", "opt", "episodes")}

    return run
