#!/bin/sh
# Regenerates the committed model files with `model-export export`: the firmware's
# default model firmware/src/model/default_model.rs (a seeded network: the trained demo
# model replaces it later, `demo --install`) and the test kit's fixture models in
# test-kit/src/fixtures/ (golden_*, bench_*).
# Usage: firmware/scripts/regenerate-models.sh ROBOT.toml   (the default robot's DH TOML)
# Every file is placed as its own board image would place it: its arrays, then an
# integer network's activation tables, go to SRAM when they fit the board's SRAM budget
# (`--budgets`, `--weights-in auto`), to flash otherwise. The QEMU bench binary, which
# holds several boards' networks together, has its own RAM budget for that
# (host-tests/budgets.toml). Seeded networks carry no training envelope (unbounded); the
# PyTorch fixture is exported with `--no-envelope`, an explicit choice for a test fixture.
set -eu
ROBOT=${1:?usage: $0 ROBOT.toml}
cd "$(dirname "$0")/../.."
cargo build -q -p model-export
ME=${CARGO_TARGET_DIR:-target}/debug/model-export
D=test-kit/src/fixtures
$ME export --dims 9,64,64,3 --seed 1 --precision int16 --robot "$ROBOT" --budgets host-tests/budgets.toml --out firmware/src/model/default_model.rs
for p in f32 int16 int8; do
  $ME export --dims 5,12,8,3 --seed 7 --preset custom --joints 1,2,3 --precision $p --self-check-steps 10000 --budgets host-tests/budgets.toml --out $D/golden_$p.rs
  $ME export --dims 9,64,64,3 --seed 2 --precision $p --robot "$ROBOT" --budgets host-tests/budgets.toml --out $D/bench_paper_$p.rs
done
$ME export --dims 3,16,16,1 --seed 3 --joints 5 --precision int16 --budgets host-tests/budgets.toml --out $D/bench_joint_int16.rs
$ME export --dims 11,16,16,1 --seed 4 --preset drive --joints 5 --precision int16 --budgets host-tests/budgets.toml --out $D/bench_drive_int16.rs
# The PyTorch fixture with a linear input layer (scripts/make_torch_fixture.py).
for p in f32 int16 int8; do
  $ME export --network crates/compnet/tests/fixtures/torch_linear.safetensors --joints 1,2 --precision $p --self-check-steps 10000 --allow-worse --no-envelope --budgets host-tests/budgets.toml --out $D/golden_linear_$p.rs
done
