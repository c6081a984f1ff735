#!/usr/bin/env bash
# Runs every fuzz target of fuzz/ (cargo fuzz, libFuzzer) for SECONDS each (default 20) and fails
# if any crashes, panics, hangs (10 s on one input) or runs out of memory (2 GiB).
#   ./scripts/fuzz.sh             # 20 s per target
#   ./scripts/fuzz.sh 600 mesh_ply mesh_gz   # longer, only these targets
# Stable Rust: `-s none` (no sanitizer), debug assertions on. Everything it makes stays under
# target/fuzz: the build, each target's growing corpus (corpus/TARGET, seeded from the
# committed fuzz/corpus/TARGET) and the input of any crash (artifacts/TARGET/). A crash is
# reproduced with `cargo fuzz run -s none -a --fuzz-dir fuzz --target-dir target/fuzz TARGET FILE`
# and becomes a regression test.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
secs=${1:-20}
shift || true

scripts/provision.sh fuzz   # cargo-fuzz, pinned (installed once)

out=$root/target/fuzz
opts=(-s none -a --fuzz-dir "$root/fuzz" --target-dir "$out")
if [[ $# -gt 0 ]]; then targets=("$@"); else mapfile -t targets < <(cargo fuzz list --fuzz-dir "$root/fuzz"); fi

if [[ $# -gt 0 ]]; then
  for t in "${targets[@]}"; do cargo fuzz build "${opts[@]}" "$t"; done
else
  cargo fuzz build "${opts[@]}"
fi
failed=()
for t in "${targets[@]}"; do
  mkdir -p "$out/corpus/$t" "$out/artifacts/$t"
  echo "fuzz: $t for ${secs}s"
  if ! cargo fuzz run "${opts[@]}" "$t" "$out/corpus/$t" "$root/fuzz/corpus/$t" -- \
      -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
      -artifact_prefix="$out/artifacts/$t/" -print_final_stats=1 \
      >"$out/$t.log" 2>&1; then
    failed+=("$t")
    tail -n 40 "$out/$t.log"
  fi
  grep -E "^(Done|stat::number_of_executed_units|stat::new_units_added)" "$out/$t.log" | tr '\n' ' '
  echo
done
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "fuzz: FAILED: ${failed[*]} (inputs in $out/artifacts/)"
  exit 1
fi
echo "fuzz: ${#targets[@]} targets, ${secs}s each, no crash"
