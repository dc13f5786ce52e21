#!/bin/sh
# One-time migration of the committed trained model (firmware/src/model/default_model.rs,
# written by `demo --install` before the exporter chose a placement; it cannot be
# regenerated from a seed): adds the exporter's placement of a model of the same shape
# (a seeded export with the same sizes, precision and robot, `--weights-in auto`
# against host-tests/budgets.toml), i.e. its `// Placement:` header line and its
# `link_section` attribute line before NETWORK, LINEAR_STAGE and DYNAMICS, and
# recomputes CONTENT_HASH (SHA-256, first 8 bytes, of everything below that line).
# Usage: firmware/scripts/place-default-model.sh ROBOT.toml [MODEL.rs]
set -eu
ROBOT=${1:?usage: $0 ROBOT.toml [MODEL.rs]}
cd "$(dirname "$0")/../.."
F=${2:-firmware/src/model/default_model.rs}
cargo build -q -p model-export
ME=${CARGO_TARGET_DIR:-target}/debug/model-export
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
if grep -q '^// Placement:' "$F"; then
  echo "$F already records its placement"
  exit 0
fi
# "// Network 9x64x64x3 (Int16)": the shape whose seeded export gives the placement.
shape=$(sed -n 2p "$F" | sed -n 's/^\/\/ Network \([0-9]*\)x\([0-9]*\)x\([0-9]*\)x\([0-9]*\) (\([A-Za-z0-9]*\)).*/\1,\2,\3,\4 \5/p')
[ -n "$shape" ] || { echo "$F: line 2: no network shape" >&2; exit 1; }
dims=${shape% *}
prec=$(echo "${shape#* }" | tr 'A-Z' 'a-z')
$ME export --dims "$dims" --seed 1 --precision "$prec" --robot "$ROBOT" \
  --budgets host-tests/budgets.toml --out "$T/seeded.rs" >/dev/null
[ "$(grep -c '^pub static DYNAMICS: RigidBodyModel<' "$F")" = "$(grep -c '^pub static DYNAMICS: RigidBodyModel<' "$T/seeded.rs")" ] \
  || { echo "$F: its rigid-body model differs from $ROBOT's" >&2; exit 1; }
place=$(grep '^// Placement:' "$T/seeded.rs")
# Each static gets the attribute line the seeded export put before it (if any).
awk -v place="$place" '
  FNR == NR {
    if (prev ~ /^#\[cfg_attr\(target_os = "none", .*link_section = "[.a-z_]*"\)+\]$/ && $0 ~ /^pub static [A-Z_]*:/) {
      split($0, w, /[ :]/); attr[w[3]] = prev
    }
    prev = $0; next
  }
  FNR == 3 { print place }
  /^pub static [A-Z_]*:/ { split($0, w, /[ :]/); if (w[3] in attr) print attr[w[3]] }
  $0 == "/// The network (flash)." { print "/// The network."; next }
  { print }
' "$T/seeded.rs" "$F" > "$T/placed.rs"
n=$(grep -n '^pub const CONTENT_HASH: u64 = ' "$T/placed.rs" | cut -d: -f1)
hash=$(tail -n +"$((n + 1))" "$T/placed.rs" | sha256sum | cut -c1-16)
sed "${n}s/.*/pub const CONTENT_HASH: u64 = 0x$hash;/" "$T/placed.rs" > "$T/hashed.rs"
mv "$T/hashed.rs" "$F"
echo "$F: $place"
