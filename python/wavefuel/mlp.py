"""Learned controllers (docs/controllers.md, "mlp: learned controllers"): the network file of a `model: mlp` driver
group, written from numpy arrays or a PyTorch nn.Sequential (export_mlp), read back (read_mlp), evaluated by the
library (Network: the code a run uses) and, independently, in numpy (mlp_forward: the tests' reference).

The network maps an observation row [own speed m/s, leader speed m/s, gap m] (Simulation.observe) to a command:
x = (row - input_mean) / input_std; x = act(W x + b) for each layer; command = clip(x * output_scale +
output_offset, output_min, output_max), an acceleration (m/s^2) or a set speed (m/s, followed by the acc law)."""
import ctypes as C
import os

import numpy as np

from ._lib import WfError, check, lib

FORMAT = "wavefuel-mlp 1"
ACTIVATIONS = ("identity", "tanh", "relu")
OUTPUTS = ("acceleration", "speed")
N_INPUTS = 3  # the observation row


def _torch_layers(module):
    """[(weight, bias, activation)] of an nn.Sequential of Linear layers, each followed by at most one Tanh, ReLU
    or Identity, in float64."""
    import torch.nn as nn  # only for a PyTorch module
    layers = []
    for m in module:
        if isinstance(m, nn.Linear):
            w = m.weight.detach().double().cpu().numpy()
            b = (m.bias.detach().double().cpu().numpy() if m.bias is not None else np.zeros(w.shape[0]))
            layers.append([w, b, "identity"])
        elif isinstance(m, (nn.Tanh, nn.ReLU, nn.Identity)):
            name = {nn.Tanh: "tanh", nn.ReLU: "relu", nn.Identity: "identity"}[type(m)]
            if not layers or layers[-1][2] != "identity":
                raise ValueError(f"export_mlp: {type(m).__name__} must follow a Linear layer (one activation each)")
            layers[-1][2] = name
        else:
            raise ValueError(f"export_mlp: {type(m).__name__} is not supported (Linear, Tanh, ReLU, Identity)")
    return [tuple(x) for x in layers]


def _as_layers(layers, activations):
    """[(weight, bias, activation)] from a torch module or from (weight, bias) pairs with `activations`: one name
    per layer, or one name for every hidden layer (the last is then identity)."""
    if hasattr(layers, "parameters") and hasattr(layers, "__iter__") and not isinstance(layers, (list, tuple)):
        if activations is not None:
            raise ValueError("export_mlp: a PyTorch module carries its own activations: do not pass activations")
        return _torch_layers(layers)
    pairs = [(np.asarray(w, np.float64), np.asarray(b, np.float64)) for w, b in layers]
    if activations is None:
        activations = "tanh"
    if isinstance(activations, str):
        activations = [activations] * (len(pairs) - 1) + ["identity"]
    if len(activations) != len(pairs):
        raise ValueError(f"export_mlp: {len(activations)} activations for {len(pairs)} layers")
    return [(w, b, a) for (w, b), a in zip(pairs, activations)]


def export_mlp(path, layers, activations=None, input_mean=(0.0, 0.0, 0.0), input_std=(1.0, 1.0, 1.0),
               output="acceleration", output_scale=1.0, output_offset=0.0, output_min=None, output_max=None,
               check_file=True):
    """Write a network file for `model: mlp` (docs/controllers.md).

    layers: a PyTorch nn.Sequential of Linear layers each followed by at most one Tanh, ReLU or Identity, or a list
    of (weight, bias) pairs, weight of shape [outputs, inputs] (PyTorch's Linear.weight), with `activations` (one of
    "identity", "tanh", "relu" per layer, or one name for every hidden layer: the last is then identity; default
    "tanh"). The first layer takes the 3 observation columns, the last gives one output. output: "acceleration"
    (m/s^2) or "speed" (a set speed, m/s). output_min/max: optional clip of the command. Everything is stored as
    float64. With check_file, the file is then read by the library, which refuses it (wavefuel.WavefuelError naming
    the dataset; the file is removed) when a shape, value or name is wrong. Returns path."""
    import h5py
    spec = _as_layers(layers, activations)
    if output not in OUTPUTS:
        raise ValueError(f"export_mlp: output must be one of {OUTPUTS} (got {output!r})")
    with h5py.File(path, "w") as f:
        f["format"] = FORMAT
        f["input/mean"] = np.asarray(input_mean, np.float64)
        f["input/std"] = np.asarray(input_std, np.float64)
        f["input/mean"].attrs["units"] = f["input/std"].attrs["units"] = "m/s, m/s, m"
        for k, (w, b, act) in enumerate(spec):
            f[f"layers/{k}/weight"] = np.asarray(w, np.float64)
            f[f"layers/{k}/bias"] = np.asarray(b, np.float64)
            f[f"layers/{k}/activation"] = act
        f["output/kind"] = output
        f["output/scale"] = float(output_scale)
        f["output/offset"] = float(output_offset)
        if output_min is not None:
            f["output/min"] = float(output_min)
        if output_max is not None:
            f["output/max"] = float(output_max)
    if check_file:
        try:
            Network(path).close()
        except Exception:
            os.remove(path)
            raise
    return path


def read_mlp(path):
    """The network of a file as a dict (h5py, no check): layers [(weight, bias, activation)], input_mean, input_std,
    output, output_scale, output_offset, output_min, output_max (-inf/inf when absent)."""
    import h5py

    def text(x):
        return x.decode() if isinstance(x, bytes) else str(x)
    with h5py.File(path, "r") as f:
        n = len(f["layers"])
        layers = [(f[f"layers/{k}/weight"][()], f[f"layers/{k}/bias"][()], text(f[f"layers/{k}/activation"][()]))
                  for k in range(n)]
        out = f["output"]
        return {"layers": layers, "input_mean": f["input/mean"][()], "input_std": f["input/std"][()],
                "output": text(out["kind"][()]), "output_scale": float(out["scale"][()]),
                "output_offset": float(out["offset"][()]),
                "output_min": float(out["min"][()]) if "min" in out else -np.inf,
                "output_max": float(out["max"][()]) if "max" in out else np.inf}


def mlp_forward(net, rows):
    """The network's commands for rows of [own speed, leader speed, gap] (an (n, 3) array), in numpy float64: the
    independent reference of the library's evaluation. net: a path or read_mlp()'s dict."""
    if not isinstance(net, dict):
        net = read_mlp(net)
    x = (np.asarray(rows, np.float64).reshape(-1, N_INPUTS) - net["input_mean"]) / net["input_std"]
    for w, b, act in net["layers"]:
        x = x @ np.asarray(w).T + b
        if act == "tanh":
            x = np.tanh(x)
        elif act == "relu":
            x = np.maximum(x, 0.0)
        elif act != "identity":
            raise ValueError(f"unknown activation {act!r}")
    u = x[:, 0] * net["output_scale"] + net["output_offset"]
    return np.clip(u, net["output_min"], net["output_max"])


class Network:
    """A network file loaded by the library, as a `model: mlp` group loads it (the same checks and messages:
    wavefuel.WavefuelError); evaluate(rows) runs the code a simulation runs."""

    def __init__(self, path):
        self._ptr = C.c_void_p()
        err = WfError()
        check(lib.wf_mlp_load(os.fsencode(path), C.byref(self._ptr), C.byref(err)), err)
        self.path = path
        self.output = OUTPUTS[lib.wf_mlp_output(self._ptr)]

    def evaluate(self, rows, threads=1):
        """Commands (m/s^2 or m/s) for an (n, 3) array of observation rows."""
        if not self._ptr:
            raise ValueError("the network is closed")
        x = np.ascontiguousarray(rows, dtype=np.float64).reshape(-1, N_INPUTS)
        out = np.empty(x.shape[0])
        dp = C.POINTER(C.c_double)
        lib.wf_mlp_eval(self._ptr, x.ctypes.data_as(dp), x.shape[0], out.ctypes.data_as(dp), int(threads))
        return out

    def close(self):
        """Free the network now (also when the object is collected)."""
        if getattr(self, "_ptr", None) and lib is not None:  # lib is None during interpreter shutdown
            lib.wf_mlp_destroy(C.byref(self._ptr))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()
