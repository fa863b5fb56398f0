"""The pixel student's network (:func:`gym_soarm.rl.pixels.build_network` builds it): one
small convolutional encoder per camera ending in a spatial soft arg-max, the
proprioception beside the keypoints, an MLP to the action, and an optional auxiliary
head. Imports torch: import it lazily."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn


class SpatialSoftmax(nn.Module):
    """Each channel's soft arg-max: (x, y) in [-1, 1], 2 values per channel."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        n, c, h, w = x.shape
        p = torch.softmax(x.flatten(2), -1).view(n, c, h, w)
        ys = torch.linspace(-1.0, 1.0, h, device=x.device)
        xs = torch.linspace(-1.0, 1.0, w, device=x.device)
        return torch.cat([(p.sum(2) * xs).sum(2), (p.sum(3) * ys).sum(2)], 1)


def encoder(channels: Sequence[int], downsample: int) -> nn.Module:
    """One camera's encoder: an average pooling by ``downsample`` (when > 1), four
    convolutions of ``channels``, the spatial soft arg-max."""
    c1, c2, c3, c4 = channels
    pool = [nn.AvgPool2d(downsample)] if downsample > 1 else []
    return nn.Sequential(
        *pool,
        nn.Conv2d(3, c1, 5, stride=2, padding=2),
        nn.ReLU(),
        nn.Conv2d(c1, c2, 3, stride=2, padding=1),
        nn.ReLU(),
        nn.Conv2d(c2, c3, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(c3, c4, 3, padding=1),
        SpatialSoftmax(),
    )


def mlp(width: int, hidden: Sequence[int], out: int) -> nn.Sequential:
    """Linear layers of ``hidden`` units with ReLUs between, then ``out`` outputs."""
    layers: list[nn.Module] = []
    for units in hidden:
        layers += [nn.Linear(width, units), nn.ReLU()]
        width = units
    layers.append(nn.Linear(width, out))
    return nn.Sequential(*layers)


class PixelNet(nn.Module):
    """See :func:`gym_soarm.rl.pixels.build_network` for the arguments."""

    def __init__(
        self,
        cameras: Sequence[str],
        act_dim: int,
        channels: Sequence[int],
        hidden: Sequence[int],
        pos_dim: int,
        downsample: int,
        aux_dim: int,
        aux_input: bool,
    ) -> None:
        super().__init__()
        self.cameras = tuple(cameras)
        self.downsample = downsample
        self.aux_input = aux_input
        self.encoders = nn.ModuleDict({c: encoder(channels, downsample) for c in self.cameras})
        keypoints = 2 * channels[-1] * len(self.cameras)
        width = keypoints + pos_dim + (aux_dim if aux_input else 0)
        self.head = mlp(width, hidden, act_dim)
        self.aux = mlp(keypoints, (128,), aux_dim) if aux_dim else None

    def encode(self, images: dict[str, torch.Tensor], pooled: bool = False) -> torch.Tensor:
        """The keypoints of every camera; ``pooled``: the images are already averaged
        down by ``downsample`` (training pools its data once)."""
        skip = 1 if pooled and self.downsample > 1 else 0
        return torch.cat([self.encoders[c][skip:](images[c] - 0.5) for c in self.cameras], 1)

    def act_from(self, keypoints: torch.Tensor, proprio: torch.Tensor) -> torch.Tensor:
        if self.aux_input:
            return self.head(torch.cat([keypoints, self.aux(keypoints), proprio], 1))
        return self.head(torch.cat([keypoints, proprio], 1))

    def forward(self, images: dict[str, torch.Tensor], proprio: torch.Tensor) -> torch.Tensor:
        return self.act_from(self.encode(images), proprio)


__all__ = ["PixelNet", "SpatialSoftmax", "encoder", "mlp"]
