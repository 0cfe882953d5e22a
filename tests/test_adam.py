"""The product's Adam steps as torch.optim.Adam does."""

import torch

from mistyle.adam import Adam


def test_adam_follows_torch_optim_adam_over_two_groups():
    generator = torch.Generator().manual_seed(0)
    target = torch.randn(5, 4, generator=generator)
    starts = [torch.randn(5, 4, generator=generator), torch.randn(3, generator=generator)]
    ours = [start.clone().requires_grad_(True) for start in starts]
    theirs = [start.clone().requires_grad_(True) for start in starts]
    mine = Adam([{"params": [ours[0]], "lr": 0.05}, {"params": [ours[1]], "lr": 0.2}])
    reference = torch.optim.Adam([{"params": [theirs[0]], "lr": 0.05}, {"params": [theirs[1]], "lr": 0.2}])
    for _ in range(25):
        for params, optimizer in ((ours, mine), (theirs, reference)):
            optimizer.zero_grad()
            loss = ((params[0] - target) ** 2).sum() + (params[1] ** 4).sum()
            loss.backward()
            optimizer.step()
    for a, b in zip(ours, theirs):
        assert torch.allclose(a, b, atol=1e-6, rtol=1e-5)
    assert not torch.allclose(ours[0], starts[0])


def test_a_parameter_without_a_gradient_stays_put():
    free, idle = torch.ones(3, requires_grad=True), torch.ones(2, requires_grad=True)
    optimizer = Adam([free, idle], lr=0.1)
    (free**2).sum().backward()
    optimizer.step()
    assert torch.equal(idle, torch.ones(2)) and not torch.equal(free.detach(), torch.ones(3))
