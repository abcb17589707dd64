#!/usr/bin/env python3
"""Reference timings with PyTorch Geometric for examples/feast_bench.rs.

Same workloads, same machine:
  1. one FeaStConv(64, 64, heads=8) forward + backward on the 30 x 50 triangulated torus grid
     (1,500 vertices, 9,000 directed edges; FeaStConv adds the self-loops);
  2. the graph VAE (table 4.3 sizes) forward + backward on the LV phantom written by
     `cargo run --release --example feast_bench -- --dump-phantom FILE` (optional).

Median of 30 runs after 5 warm-up runs, 2 threads.

  python3 scripts/feast_pyg_bench.py [PHANTOM_FILE]

Needs torch (CPU) and torch_geometric from PyPI.
"""

import statistics
import sys
import time

import torch
from torch import nn
from torch_geometric.nn import FeaStConv

WARM_UP, RUNS = 5, 30
GRID = (30, 50)


def median_ms(f):
    for _ in range(WARM_UP):
        f()
    times = []
    for _ in range(RUNS):
        t = time.perf_counter()
        f()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


def both_ways(pairs):
    e = torch.tensor(pairs, dtype=torch.long).t()
    return torch.cat([e, e.flip(0)], dim=1)


def torus_grid():
    a, b = GRID

    def vid(i, j):
        return (i % a) * b + (j % b)

    pairs = []
    for i in range(a):
        for j in range(b):
            pairs += [(vid(i, j), vid(i + 1, j)), (vid(i, j), vid(i, j + 1)), (vid(i, j), vid(i + 1, j + 1))]
    return a * b, both_ways(pairs)


def bench_layer():
    torch.manual_seed(0)
    n, edge_index = torus_grid()
    conv = FeaStConv(64, 64, heads=8)
    x0 = torch.randn(n, 64)

    def step():
        x = x0.clone().requires_grad_(True)
        conv.zero_grad()
        conv(x, edge_index).sum().backward()

    ms = median_ms(step)
    print(f"feast_layer pyg vertices={n} edges={edge_index.shape[1]} channels=64 heads=8 fwd+bwd median={ms:.2f} ms")


class Block(nn.Module):
    def __init__(self, d_in, d_out):
        super().__init__()
        self.conv, self.norm = FeaStConv(d_in, d_out, heads=8), nn.BatchNorm1d(d_out)

    def forward(self, x, e):
        return nn.functional.leaky_relu(self.norm(self.conv(x, e)))


class Psi(nn.Module):
    def __init__(self, d_x=3, hidden=(64, 64, 128), d_z=128):
        super().__init__()
        enc = [d_x, *hidden]
        dec = [d_z, *reversed(hidden)]
        self.encoder = nn.ModuleList(Block(a, b) for a, b in zip(enc, enc[1:]))
        self.mean, self.log_sigma = FeaStConv(hidden[-1], d_z, heads=8), FeaStConv(hidden[-1], d_z, heads=8)
        self.decoder = nn.ModuleList(Block(a, b) for a, b in zip(dec, dec[1:]))
        self.output = FeaStConv(hidden[0], d_x, heads=8)

    def loss(self, x, e, noise, w_kl=1e-3):
        h = x
        for b in self.encoder:
            h = b(h, e)
        mu, ls = self.mean(h, e), self.log_sigma(h, e).clamp(-10, 10)
        z = mu + ls.exp() * noise
        for b in self.decoder:
            z = b(z, e)
        x_hat = self.output(z, e)
        kl = (0.5 * (mu**2 + (2 * ls).exp()) - ls - 0.5).sum()
        return 0.5 * ((x_hat - x) ** 2).sum() + w_kl * kl


def bench_psi(path):
    pos, pairs = [], []
    with open(path) as f:
        for line in f:
            kind, *v = line.split()
            if kind == "v":
                pos.append([float(t) for t in v])
            elif kind == "e":
                pairs.append((int(v[0]), int(v[1])))
    x = torch.tensor(pos)
    x = (x - x.mean(0)) / ((x - x.mean(0)) ** 2).sum(1).mean().sqrt()
    e = both_ways(pairs)
    torch.manual_seed(1)
    model = Psi()
    noise = torch.randn(x.shape[0], 128)

    def fwd_bwd():
        model.zero_grad()
        model.loss(x, e, noise).backward()

    opt = torch.optim.Adam(model.parameters(), lr=1e-3)

    def train_step():
        opt.zero_grad()
        model.loss(x, e, noise).backward()
        opt.step()

    a, b = median_ms(fwd_bwd), median_ms(train_step)
    params = sum(p.numel() for p in model.parameters())
    print(
        f"psi pyg lv_phantom vertices={x.shape[0]} edges={e.shape[1]} params={params} "
        f"fwd+bwd median={a:.1f} ms, train step (with Adam) median={b:.1f} ms"
    )


if __name__ == "__main__":
    torch.set_num_threads(2)
    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}")
    bench_layer()
    if len(sys.argv) > 1:
        bench_psi(sys.argv[1])
