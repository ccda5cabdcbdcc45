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

# Demo plant: four lanes of simulated fillets, replayed through the pipeline and evaluated
# against the simulator's truth.
demo=build/demo
rm -rf "$demo"
mkdir -p "$demo"
ctl=build/client/rangexctl
"$ctl" simulate --lanes 4 --fillets 3 --seed 1 --out "$demo/recording"
"$ctl" process "$demo/recording" --out "$demo/out"
echo
"$ctl" eval "$demo/recording" "$demo/out"
echo
echo "images: $demo/out/lane*/thickness.png (0.01 mm per count) and xray.png"
