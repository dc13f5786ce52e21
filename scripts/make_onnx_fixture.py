#!/usr/bin/env python3
"""Writes the ONNX interchange fixtures for the import tests, as current PyTorch exports them.

Builds the same compensation network as scripts/make_torch_fixture.py (nn.Linear -> tanh
-> nn.LSTM -> nn.Linear with normalisation buffers, same seed and sizes) and exports it with
both of PyTorch's ONNX exporters:

| file | exporter | LSTM |
|---|---|---|
| torch_lstm.onnx | TorchScript (`dynamo=False`) | `batch_first=True` |
| torch_lstm_time_first.onnx | TorchScript (`dynamo=False`) | `batch_first=False` (PyTorch's default) |
| torch_lstm_dynamo.onnx | `torch.onnx.export` with default settings (the dynamo-based exporter of current PyTorch) | `batch_first=False` |
| torch_lstm_dynamo_batch_first.onnx | the dynamo-based exporter | `batch_first=True` |
| torch_lstm_2layer.onnx, torch_lstm_2layer_dynamo.onnx | both | `num_layers=2` (refused: the firmware runs one layer) |

The feature names go into each model's metadata_props. A reference sequence is streamed
through onnxruntime (onnx_reference_<variant>.csv, columns t, x0.., y0..; the TorchScript
batch-first one also through the PyTorch module, onnx_reference.csv), and the script fails
when onnxruntime and PyTorch differ by more than 1e-5 of the output's RMS.

    pip install torch onnx onnxscript onnxruntime
    python3 scripts/make_onnx_fixture.py crates/compnet/tests/fixtures

It also copies every variant into fuzz/corpus/onnx_<variant>/ (the fuzz seeds: torchscript,
time_first, dynamo, dynamo_batch_first) when run from the workspace root.
"""
import shutil
import sys
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch
from torch import nn

I, E, H, O, T = 5, 12, 16, 2, 400


class Compensator(nn.Module):
    def __init__(self, batch_first=True, num_layers=1):
        super().__init__()
        self.batch_first = batch_first
        self.input = nn.Linear(I, E)
        self.lstm = nn.LSTM(E, H, num_layers=num_layers, batch_first=batch_first)
        self.output = nn.Linear(H, O)
        self.register_buffer("input_mean", torch.linspace(-1.0, 1.0, I))
        self.register_buffer("input_std", torch.linspace(0.5, 2.0, I))
        self.register_buffer("output_mean", torch.tensor([3.0, -1.5]))
        self.register_buffer("output_std", torch.tensor([2.0, 0.25]))

    def forward(self, x):
        e = torch.tanh(self.input((x - self.input_mean) / self.input_std))
        h, _ = self.lstm(e)
        return self.output(h) * self.output_std + self.output_mean


def network(batch_first=True, num_layers=1):
    # The same seed for every variant: the same weights whatever the layout.
    torch.manual_seed(20201)
    return Compensator(batch_first, num_layers).float().eval()


def sequence():
    t = torch.arange(T, dtype=torch.float32)
    return torch.stack([2.0 * torch.sin(t * (0.02 + 0.013 * k)) + 0.5 * torch.cos(t * 0.37 * (k + 1))
                        for k in range(I)], dim=1)


def batched(x, batch_first):
    """[T, I] as the module's input: [1, T, I] batch-first, [T, 1, I] time-first."""
    return x.unsqueeze(0) if batch_first else x.unsqueeze(1)


def export(m, path, batch_first, dynamo):
    x = batched(sequence()[:10], batch_first)
    if dynamo:
        # torch.onnx.export's defaults (the dynamo-based exporter in current PyTorch): the
        # shapes are those of the example, so it is the whole reference sequence.
        x = batched(sequence(), batch_first)
        torch.onnx.export(m, (x,), str(path), input_names=["x"], output_names=["y"])
    else:
        axes = {0: "batch", 1: "time"} if batch_first else {0: "time", 1: "batch"}
        torch.onnx.export(m, (x,), str(path), input_names=["x"], output_names=["y"],
                          dynamic_axes={"x": axes, "y": axes}, opset_version=17, dynamo=False)
    model = onnx.load(str(path), load_external_data=True)
    del model.metadata_props[:]
    for k, v in {"input_names": ",".join(f"x{k}" for k in range(I)),
                 "output_names": ",".join(f"y{k}" for k in range(O)),
                 "preset": "custom"}.items():
        model.metadata_props.add(key=k, value=v)
    model.producer_name = "pytorch"
    model.doc_string = (f"torch {torch.__version__}, {'dynamo' if dynamo else 'TorchScript'} exporter, "
                        f"batch_first={batch_first}, scripts/make_onnx_fixture.py")
    onnx.checker.check_model(model)
    # One self-contained file (the dynamo exporter may write weights beside it).
    onnx.save(model, str(path), save_as_external_data=False)
    for extra in path.parent.glob(path.name + ".data"):
        extra.unlink()
    return model


def run_ort(path, x, batch_first):
    """The whole sequence through onnxruntime (one batch), [T, O]."""
    s = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    name = s.get_inputs()[0].name
    xs = batched(x, batch_first).numpy()
    if any(isinstance(d, int) and d != n for d, n in zip(s.get_inputs()[0].shape, xs.shape)):
        # A graph exported with a static time axis: step it with the same length.
        raise SystemExit(f"{path}: static input shape {s.get_inputs()[0].shape}, need {list(xs.shape)}")
    y = s.run(None, {name: xs})[0]
    return y[0] if batch_first else y[:, 0]


def write_reference(path, x, y):
    with open(path, "w") as f:
        f.write(",".join(["t"] + [f"x{k}" for k in range(I)] + [f"y{k}" for k in range(O)]) + "\n")
        for r in range(T):
            f.write(",".join([str(r)] + [repr(float(v)) for v in x[r]] + [repr(float(v)) for v in y[r]]) + "\n")


def main(out_dir: Path):
    torch.set_num_threads(1)
    out_dir.mkdir(parents=True, exist_ok=True)
    x = sequence()
    fuzz = Path("fuzz/corpus")
    variants = [
        ("torch_lstm", True, False, 1),
        ("torch_lstm_time_first", False, False, 1),
        ("torch_lstm_dynamo", False, True, 1),
        ("torch_lstm_dynamo_batch_first", True, True, 1),
        ("torch_lstm_2layer", True, False, 2),
        ("torch_lstm_2layer_dynamo", False, True, 2),
    ]
    for name, batch_first, dynamo, layers in variants:
        m = network(batch_first, layers)
        with torch.no_grad():
            y_torch = m(batched(x, batch_first))
            y_torch = (y_torch[0] if batch_first else y_torch[:, 0]).numpy()
        path = out_dir / f"{name}.onnx"
        model = export(m, path, batch_first, dynamo)
        y_ort = run_ort(path, x, batch_first)
        rms = np.sqrt((y_torch.astype(np.float64) ** 2).mean(axis=0))
        err = float((np.abs(y_ort - y_torch) / rms).max())
        print(f"{name}: torch {torch.__version__}, onnxruntime {ort.__version__}, opset "
              f"{[o.version for o in model.opset_import]}, ort vs torch max error {err:.2e} of RMS; graph:")
        for n in model.graph.node:
            print(f"  {n.op_type:16s} {n.name}: {list(n.input)} -> {list(n.output)}")
        assert err < 1e-5, err
        if layers == 1:
            if name == "torch_lstm":
                write_reference(out_dir / "onnx_reference.csv", x, y_torch)
            else:
                write_reference(out_dir / f"onnx_reference_{name[len('torch_lstm_'):]}.csv", x, y_ort)
        if fuzz.is_dir():
            # One corpus per exporter variant; the 2-layer exports join their exporter's.
            variant = {"torch_lstm": "torchscript", "torch_lstm_2layer": "torchscript",
                       "torch_lstm_2layer_dynamo": "dynamo"}.get(name, name[len("torch_lstm_"):])
            d = fuzz / f"onnx_{variant}"
            d.mkdir(exist_ok=True)
            shutil.copy(path, d / path.name)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "crates/compnet/tests/fixtures"))
