"""
The optimizer step of S seeds' networks stacked in one ``(S, P)`` tensor (each row a seed's parameters), which
``train_many``'s DQN (``stacked_q``) and PPO (``stacked_ppo``) stacks share: each seed's gradient clipped as
``clip_grad_norm_`` clips a model's, then torch's Adam.

Adam is element-wise and its state is per element, so one update of the ``(S, P)`` tensor is each seed's own. It is
torch's fused CPU kernel (what ``Adam(fused=True)`` runs: one pass over the parameters, the gradient and both
moments, where the per-operation update takes eight), run with denormal floats flushed to zero
(``torch.set_flush_denormal``, the caller's setting restored after): the first moment of an input a seed saw once
decays by ``beta1`` each step into denormals (a quarter of a MiniGrid network's entries after 20,000 steps), and
arithmetic on them is about ten times slower on x86; an entry below ``2**-126`` moves a weight by less than
``1e-30 * lr``.
"""

from __future__ import annotations

import torch as th
from torch.optim.adam import adam as fused_adam

#: a denormal float32 (half the smallest normal one): it reads as 0 where denormals are flushed
DENORMAL = 2.0**-127


def clip_rows(grad: th.Tensor, max_norm: float | th.Tensor) -> None:
    """Each row of ``grad`` scaled to a 2-norm of at most ``max_norm`` (one, or an ``(S, 1)`` column): ``clip_grad_norm_``."""
    total = th.linalg.vector_norm(grad, 2, dim=1, keepdim=True)
    grad.mul_(th.clamp(max_norm / (total + 1e-6), max=1.0))


def adam(param: th.Tensor, grad: th.Tensor, exp_avg: th.Tensor, exp_avg_sq: th.Tensor, step: int,
         betas: tuple[float, float], eps: float, learning_rate: float | th.Tensor, weight_decay: float = 0.0) -> None:
    """
    Adam's step number ``step`` (1 for the first) of the ``(S, P)`` parameters by their gradient, its moments in place;
    ``learning_rate`` one for every seed or an ``(S, 1)`` column (one kernel call per distinct rate, on its seeds' rows).
    """
    if isinstance(learning_rate, float):
        groups = [(learning_rate, [param], [grad], [exp_avg], [exp_avg_sq])]
    else:
        rates = learning_rate.reshape(-1).tolist()
        groups = []
        for rate in dict.fromkeys(rates):
            rows = [i for i, r in enumerate(rates) if r == rate]
            groups.append((rate, *([t[i] for i in rows] for t in (param, grad, exp_avg, exp_avg_sq))))
    flushing = th.tensor(DENORMAL).item() == 0.0
    th.set_flush_denormal(True)
    try:
        with th.no_grad():
            for rate, params, grads, moments, squares in groups:
                steps = [th.tensor(float(step - 1)) for _ in params]  # (the functional counts each one up)
                fused_adam(params, grads, moments, squares, [], steps, fused=True, lr=rate, beta1=betas[0],
                           beta2=betas[1], weight_decay=weight_decay, eps=eps, amsgrad=False, maximize=False)
    finally:
        th.set_flush_denormal(flushing)
