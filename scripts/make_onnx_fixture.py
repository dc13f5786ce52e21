#!/usr/bin/env python3
"""Writes the ONNX interchange fixture for model-export's import test.

Builds the same compensation network as scripts/make_torch_fixture.py (nn.Linear -> tanh
-> nn.LSTM -> nn.Linear with normalisation buffers, same seed and sizes), exports it with
torch.onnx.export (the TorchScript exporter, which writes PyTorch's LSTM as one ONNX LSTM
node), records the feature names in the model's metadata_props, and streams a reference
sequence through the PyTorch module.

    python3 -m venv venv && venv/bin/pip install torch onnx
    venv/bin/python scripts/make_onnx_fixture.py crates/compnet/tests/fixtures

Outputs: torch_lstm.onnx and onnx_reference.csv (columns t, x0.., y0..).
"""
import sys
from pathlib import Path

import onnx
import torch
from torch import nn

I, E, H, O, T = 5, 12, 16, 2, 400


class Compensator(nn.Module):
    def __init__(self):
        super().__init__()
        self.input = nn.Linear(I, E)
        self.lstm = nn.LSTM(E, H, batch_first=True)
        self.output = nn.Linear(H, O)
        self.register_buffer("input_mean", torch.linspace(-1.0, 1.0, I))
        self.register_buffer("input_std", torch.linspace(0.5, 2.0, I))
        self.register_buffer("output_mean", torch.tensor([3.0, -1.5]))
        self.register_buffer("output_std", torch.tensor([2.0, 0.25]))

    def forward(self, x):
        e = torch.tanh(self.input((x - self.input_mean) / self.input_std))
        h, _ = self.lstm(e)
        return self.output(h) * self.output_std + self.output_mean


def main(out_dir: Path):
    torch.manual_seed(20201)
    torch.set_num_threads(1)
    m = Compensator().float().eval()
    t = torch.arange(T, dtype=torch.float32)
    x = torch.stack([2.0 * torch.sin(t * (0.02 + 0.013 * k)) + 0.5 * torch.cos(t * 0.37 * (k + 1))
                     for k in range(I)], dim=1)
    with torch.no_grad():
        y = m(x.unsqueeze(0)).squeeze(0)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "torch_lstm.onnx"
    torch.onnx.export(m, (x[:10].unsqueeze(0),), str(path), input_names=["x"], output_names=["y"],
                      dynamic_axes={"x": {0: "batch", 1: "time"}, "y": {0: "batch", 1: "time"}},
                      opset_version=17, dynamo=False)
    model = onnx.load(str(path))
    for k, v in {"input_names": ",".join(f"x{k}" for k in range(I)),
                 "output_names": ",".join(f"y{k}" for k in range(O)),
                 "preset": "custom"}.items():
        model.metadata_props.add(key=k, value=v)
    model.producer_name = "pytorch"
    model.doc_string = f"torch {torch.__version__}, scripts/make_onnx_fixture.py"
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    with open(out_dir / "onnx_reference.csv", "w") as f:
        f.write(",".join(["t"] + [f"x{k}" for k in range(I)] + [f"y{k}" for k in range(O)]) + "\n")
        for r in range(T):
            f.write(",".join([str(r)] + [repr(float(v)) for v in x[r]] + [repr(float(v)) for v in y[r]]) + "\n")
    print(f"wrote {path} and onnx_reference.csv ({T} steps); graph:")
    for n in model.graph.node:
        print(f"  {n.op_type:10s} {n.name}: {list(n.input)} -> {list(n.output)}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "crates/compnet/tests/fixtures"))
