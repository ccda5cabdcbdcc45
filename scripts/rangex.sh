#!/usr/bin/env bash
# The README's two commands: `scripts/rangex.sh demo` (the demo plant) and
# `scripts/rangex.sh test` (the test suite). Both install the Debian packages and build.
set -euo pipefail
cd "$(dirname "$0")/.."

what=${1:-}
case "$what" in demo | test) ;; *)
  echo "usage: scripts/rangex.sh demo|test" >&2
  exit 2
  ;;
esac

scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)"

if [ "$what" = test ]; then
  cd build
  exec ctest --output-on-failure --parallel "$(nproc)" --timeout 900
fi

# Demo plant, part 1: a small recording (4 lanes, 2 fillets each) written to disk, replayed
# through the pipeline and evaluated against the simulator's truth.
demo=build/demo
rm -rf "$demo"
mkdir -p "$demo"
ctl=build/client/rangexctl
"$ctl" simulate --lanes 4 --fillets 2 --seed 1 --out "$demo/recording"
"$ctl" process "$demo/recording" --out "$demo/recording-out"
echo
"$ctl" eval "$demo/recording" "$demo/recording-out"
echo
# Part 2: the plant at scale, 4 lanes x 125 fillets simulated in memory (no recording) and
# inspected: bone recall, false rejects and the X-ray-only baseline beside rangex.
"$ctl" process --simulate --lanes 4 --fillets 125 --seed 1 --out "$demo/plant"
echo
echo "images: $demo/recording-out/lane*/fillet_*/ (overlay.png, xray.png, thickness.png,"
echo "        pseudo_xray.png, residual.png) and $demo/plant/lane*/fillet_*/ for every reject"
