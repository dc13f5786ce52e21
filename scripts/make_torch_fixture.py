#!/usr/bin/env python3
"""Writes the PyTorch interchange fixtures for model-export's import tests.

Builds the compensation network in PyTorch (nn.Linear -> tanh -> nn.LSTM -> nn.Linear,
with normalisation buffers) from a fixed seed, saves its weights as safetensors with
PyTorch's own parameter names, and streams a reference sequence through it; then the
same with a plain nn.Linear input layer (no activation: `input_activation` `linear`),
from its own seed.

    pip install torch safetensors
    python3 scripts/make_torch_fixture.py crates/compnet/tests/fixtures

Outputs: torch_lstm.safetensors and torch_reference.csv (tanh input layer),
torch_linear.safetensors and torch_linear_reference.csv (linear input layer); the CSVs
have the columns t, x0.., y0...
"""
import sys
from pathlib import Path

import torch
from torch import nn
from safetensors.torch import save_file

I, E, H, O, T = 5, 12, 16, 2, 400


class Compensator(nn.Module):
    def __init__(self, activation):
        super().__init__()
        self.activation = activation
        self.input = nn.Linear(I, E)
        self.lstm = nn.LSTM(E, H, batch_first=True)
        self.output = nn.Linear(H, O)
        self.register_buffer("input_mean", torch.linspace(-1.0, 1.0, I))
        self.register_buffer("input_std", torch.linspace(0.5, 2.0, I))
        self.register_buffer("output_mean", torch.tensor([3.0, -1.5]))
        self.register_buffer("output_std", torch.tensor([2.0, 0.25]))

    def forward(self, x, state=None):
        e = self.input((x - self.input_mean) / self.input_std)
        if self.activation == "tanh":
            e = torch.tanh(e)
        h, state = self.lstm(e, state)
        return self.output(h) * self.output_std + self.output_mean, state

    def tensors(self):
        t = {k: v.detach().contiguous() for k, v in self.state_dict().items()}
        for k in ["input_mean", "input_std", "output_mean", "output_std"]:
            t["norm." + k] = t.pop(k)
        return t


def write(out_dir: Path, activation: str, seed: int, stem: str, reference: str):
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    m = Compensator(activation).float()
    t = torch.arange(T, dtype=torch.float32)
    x = torch.stack([2.0 * torch.sin(t * (0.02 + 0.013 * k)) + 0.5 * torch.cos(t * 0.37 * (k + 1)) for k in range(I)], dim=1)
    with torch.no_grad():
        y, _ = m(x.unsqueeze(0))
    y = y.squeeze(0)
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = {"input_names": ",".join(f"x{k}" for k in range(I)),
            "output_names": ",".join(f"y{k}" for k in range(O)),
            "preset": "custom", "input_activation": activation,
            "source": f"torch {torch.__version__}, scripts/make_torch_fixture.py"}
    save_file(m.tensors(), str(out_dir / f"{stem}.safetensors"), metadata=meta)
    with open(out_dir / reference, "w") as f:
        f.write(",".join(["t"] + [f"x{k}" for k in range(I)] + [f"y{k}" for k in range(O)]) + "\n")
        for r in range(T):
            f.write(",".join([str(r)] + [repr(float(v)) for v in x[r]] + [repr(float(v)) for v in y[r]]) + "\n")
    print(f"wrote {out_dir}/{stem}.safetensors and {reference} ({T} steps, {activation} input layer)")


def main(out_dir: Path):
    write(out_dir, "tanh", 20201, "torch_lstm", "torch_reference.csv")
    write(out_dir, "linear", 20202, "torch_linear", "torch_linear_reference.csv")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "crates/compnet/tests/fixtures"))
