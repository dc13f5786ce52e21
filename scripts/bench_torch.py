#!/usr/bin/env python3
"""PyTorch reference for model-export's `lstm_epoch` benchmark: seconds per training
epoch of the paper's configuration (9 -> 64 -> LSTM 64 -> 3, windows of 100 steps plus a
burn-in prefix, batch 50, Adam, RMS loss, gradient clipping) on a 60 000-step dataset,
on the CPU with 2 threads. Same windowing and work as the Rust benchmark. Prints wall-clock
and process CPU seconds per epoch (the latter is what to compare on a loaded machine).

    pip install torch
    python3 scripts/bench_torch.py [--burn-in 50] [--epochs 3] [--threads 2]
"""
import argparse
import time

import torch
from torch import nn


class Compensator(nn.Module):
    def __init__(self, i, e, h, o):
        super().__init__()
        self.input = nn.Linear(i, e)
        self.lstm = nn.LSTM(e, h, batch_first=True)
        self.output = nn.Linear(h, o)

    def forward(self, x):
        h, _ = self.lstm(torch.tanh(self.input(x)))
        return self.output(h)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=60000)
    p.add_argument("--window", type=int, default=100)
    p.add_argument("--burn-in", type=int, default=50)
    p.add_argument("--batch", type=int, default=50)
    p.add_argument("--hidden", type=int, default=64)
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--threads", type=int, default=2)
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    torch.manual_seed(1)
    n_in, n_out = 9, 3
    t = torch.arange(a.steps, dtype=torch.float32)
    x = torch.stack([torch.sin(t * 0.01 * (k + 1)) for k in range(n_in)], 1)
    y = torch.stack([torch.cos(t * 0.013 * (k + 1)) for k in range(n_out)], 1)
    length = a.burn_in + a.window
    starts = list(range(0, a.steps - length + 1, a.window))
    xw = torch.stack([x[s:s + length] for s in starts])
    yw = torch.stack([y[s + a.burn_in:s + length] for s in starts])
    m = Compensator(n_in, a.hidden, a.hidden, n_out)
    opt = torch.optim.Adam(m.parameters(), lr=0.003)
    times = []
    cpu = []
    for ep in range(a.epochs + 1):
        perm = torch.randperm(len(starts))
        t0 = time.perf_counter()
        c0 = time.process_time()
        for b in range(0, len(starts), a.batch):
            idx = perm[b:b + a.batch]
            pred = m(xw[idx])[:, a.burn_in:]
            loss = torch.sqrt(torch.mean((pred - yw[idx]) ** 2))
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(m.parameters(), 1.0)
            opt.step()
        if ep > 0:
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    nb = (len(starts) + a.batch - 1) // a.batch
    best = min(times)
    print(f"torch {torch.__version__}, {a.threads} threads: {len(starts)} windows of {a.burn_in}+{a.window} steps, "
          f"{nb} batches of {a.batch}, H={a.hidden}")
    print(f"| framework | s/epoch (best of {a.epochs}) | ms/batch | CPU s/epoch (best) |")
    print(f"|---|---:|---:|---:|")
    print(f"| pytorch | {best:.3f} | {1000 * best / nb:.1f} | {min(cpu):.3f} |")


if __name__ == "__main__":
    main()
