"""Explicit forward and backward passes of a ReLU MLP into preallocated buffers.

The DDPG update is a dozen small matrix products per network; on a CPU, autograd's bookkeeping
and the fresh tensors it allocates for every activation and gradient cost about as much as the
products themselves. The learner therefore writes the two passes out: every product goes into a
buffer allocated once per batch size, ReLU runs in place, its backward is one fused
`threshold_backward` into a buffer, and weight gradients land directly in each parameter's
`.grad`, where the optimiser reads them. The arithmetic is that of autograd (the tests compare
the gradients); the networks stay ordinary `nn.Module`s.

An MLP here is what `curious.networks.mlp` builds: Linear, ReLU, ..., Linear.
"""

from __future__ import annotations

import torch
from torch import nn

_relu_backward = torch.ops.aten.threshold_backward.grad_input


class MLPWorkspace:
    """Buffers and passes for one `nn.Sequential` MLP at one batch size."""

    def __init__(self, net: nn.Sequential, batch: int, with_grads: bool = True) -> None:
        self.linears = [m for m in net if isinstance(m, nn.Linear)]
        expected = 2 * len(self.linears) - 1
        if len(net) != expected or not all(isinstance(m, nn.ReLU) for m in list(net)[1::2]):
            raise ValueError("MLPWorkspace expects Linear, ReLU, ..., Linear")
        weight = self.linears[0].weight
        kw = {"device": weight.device, "dtype": weight.dtype}
        self.outputs = [torch.empty(batch, lin.out_features, **kw) for lin in self.linears]
        self.input_grads = [torch.empty(batch, lin.in_features, **kw) for lin in self.linears]
        self.input: torch.Tensor | None = None
        self._column_grads: dict[tuple[int, int], torch.Tensor] = {}
        for lin in self.linears if with_grads else ():
            for p in lin.parameters():
                if p.grad is None or p.grad.shape != p.shape:
                    p.grad = torch.zeros_like(p)

    @torch.no_grad()
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The MLP's output for x (batch, in); keeps the activations for `backward`."""
        self.input = x
        h = x
        last = len(self.linears) - 1
        for i, lin in enumerate(self.linears):
            out = self.outputs[i]
            torch.addmm(lin.bias, h, lin.weight.t(), out=out)
            if i < last:
                out.clamp_min_(0.0)
            h = out
        return h

    @torch.no_grad()
    def backward(
        self,
        grad_output: torch.Tensor,
        weight_grads: bool = True,
        input_grad: bool = False,
        input_columns: slice | None = None,
    ) -> torch.Tensor | None:
        """Back-propagate dL/d(output) through the last `forward`.

        With `weight_grads`, each parameter's `.grad` is overwritten with dL/dparameter. With
        `input_grad`, returns dL/d(input), or only its `input_columns` (the critic's action
        part), as a buffer valid until the next call.
        """
        if self.input is None:
            raise RuntimeError("backward() before forward()")
        g = grad_output
        for i in range(len(self.linears) - 1, -1, -1):
            lin = self.linears[i]
            below = self.outputs[i - 1] if i > 0 else self.input
            if weight_grads:
                torch.mm(g.t(), below, out=lin.weight.grad)
                torch.sum(g, dim=0, out=lin.bias.grad)
            if i == 0:
                if not input_grad:
                    return None
                if input_columns is not None:
                    start, stop, _ = input_columns.indices(lin.in_features)
                    key = (start, stop)
                    if key not in self._column_grads:
                        self._column_grads[key] = g.new_empty(g.shape[0], stop - start)
                    return torch.mm(g, lin.weight[:, start:stop], out=self._column_grads[key])
            grad_in = self.input_grads[i]
            torch.mm(g, lin.weight, out=grad_in)
            if i > 0:
                _relu_backward(grad_in, below, 0.0, grad_input=grad_in)
            g = grad_in
        return g
