"""Adam for the product's own fits (a look's, the refinement's), without ``torch.optim``'s start-up.

The first ``torch.optim`` optimizer a process makes imports ``torch._dynamo`` (1.2-2 s on this
project's CPU VM, ``experiments/profile_default.py``), which a short fit in a command-line run pays
in full. This is Kingma and Ba's algorithm as ``torch.optim.Adam`` computes it (no weight decay, no
AMSGrad), so the fits step as they did (``tests/test_adam.py`` compares the two).
"""

from __future__ import annotations

import math

import torch


class Adam:
    """``Adam(groups)``: ``groups`` a list of tensors, or of ``{"params": [...], "lr": ...}`` dicts."""

    def __init__(self, groups, lr: float = 1e-3, betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8):
        groups = list(groups)
        if groups and isinstance(groups[0], torch.Tensor):
            groups = [{"params": groups}]
        self.groups = [{"params": list(group["params"]), "lr": float(group.get("lr", lr))} for group in groups]
        self.betas, self.eps = betas, eps
        self.steps = 0
        self.moments: dict[int, tuple[torch.Tensor, torch.Tensor]] = {}

    def zero_grad(self) -> None:
        for group in self.groups:
            for parameter in group["params"]:
                parameter.grad = None

    @torch.no_grad()
    def step(self) -> None:
        beta1, beta2 = self.betas
        self.steps += 1
        correction1 = 1.0 - beta1**self.steps
        correction2 = math.sqrt(1.0 - beta2**self.steps)
        for group in self.groups:
            for parameter in group["params"]:
                if parameter.grad is None:
                    continue
                grad = parameter.grad
                if id(parameter) not in self.moments:
                    self.moments[id(parameter)] = (torch.zeros_like(parameter), torch.zeros_like(parameter))
                first, second = self.moments[id(parameter)]
                first.lerp_(grad, 1.0 - beta1)
                second.mul_(beta2).addcmul_(grad, grad, value=1.0 - beta2)
                denominator = (second.sqrt() / correction2).add_(self.eps)
                parameter.addcdiv_(first, denominator, value=-group["lr"] / correction1)
