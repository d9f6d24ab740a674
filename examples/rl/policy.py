"""The policy of examples/rl/ (PyTorch, float64): a 2 x 64 tanh MLP from the observation row [own speed m/s,
leader speed m/s, gap m], normalised by fixed input_mean / input_std, to an acceleration (m/s^2), clipped to the
action space for the deterministic action; Gaussian exploration with a learned, state-independent standard
deviation. The same layers, normalisation and clip are what wavefuel.export_mlp writes for `model: mlp`."""
import math

import numpy as np
import torch
import torch.nn as nn

from platoon import ACCEL_RANGE_MPS2

torch.set_default_dtype(torch.float64)


def mlp():
    return nn.Sequential(nn.Linear(3, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(), nn.Linear(64, 1))


class Policy(nn.Module):
    def __init__(self, input_mean, input_std, std_mps2=0.4):
        super().__init__()
        self.net = mlp()
        self.register_buffer("input_mean", torch.as_tensor(np.asarray(input_mean, np.float64)))
        self.register_buffer("input_std", torch.as_tensor(np.asarray(input_std, np.float64)))
        self.log_std = nn.Parameter(torch.tensor(math.log(std_mps2)))

    def mean(self, obs):
        """The network's output (m/s^2, before the clip) for rows of observations (a tensor [n, 3])."""
        return self.net((obs - self.input_mean) / self.input_std)[:, 0]

    def dist(self, obs):
        return torch.distributions.Normal(self.mean(obs), self.log_std.exp())

    def act(self, obs_np):
        """The deterministic action (the mean, clipped to the action space) for a numpy array of rows."""
        with torch.no_grad():
            return self.mean(torch.as_tensor(obs_np)).clamp(*ACCEL_RANGE_MPS2).numpy()


class Value(nn.Module):
    def __init__(self, policy):
        super().__init__()
        self.net, self.policy = mlp(), [policy]  # a list: the policy's modules stay out of this one's parameters

    def forward(self, obs):
        p = self.policy[0]
        return self.net((obs - p.input_mean) / p.input_std)[:, 0]


def save(path, policy, info):
    torch.save({"state": policy.state_dict(), "info": info}, path)


def load(path):
    ck = torch.load(path)
    p = Policy(ck["state"]["input_mean"].numpy(), ck["state"]["input_std"].numpy())
    p.load_state_dict(ck["state"])
    return p, ck["info"]


def export(policy, path):
    """The policy's network as a wavefuel network file (`model: mlp`, docs/controllers.md): the mean action."""
    import wavefuel
    return wavefuel.export_mlp(path, policy.net, input_mean=policy.input_mean.numpy(),
                               input_std=policy.input_std.numpy(), output="acceleration",
                               output_min=ACCEL_RANGE_MPS2[0], output_max=ACCEL_RANGE_MPS2[1])
