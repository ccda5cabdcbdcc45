#!/bin/sh
# Runs a test binary built with ThreadSanitizer: the suppressions of tsan.supp plus one
# called_from_lib line for each uninstrumented gRPC, abseil or protobuf library the binary
# loads, and without address-space randomisation where the system allows (some TSan
# runtimes cannot map their shadow memory under a kernel's randomised layout).
# clear_shadow_mmap_threshold: gRPC serialises each LineScan into a 256 KB slice that the
# allocator maps and unmaps; by default TSan re-zeroes the shadow of each such region by
# remapping it, and the page faults that follow cost most of these tests' time
# (ManyStreams 174 s -> 36 s). Regions under 4 MB are cleared by memset instead.
set -eu
bin=$1
shift
supp=$(mktemp)
trap 'rm -f "$supp"' EXIT
cat "$(dirname "$0")/tsan.supp" >"$supp"
ldd "$bin" | grep -oE 'lib(absl_[a-z0-9_]+|grpc[a-z0-9_+]*|gpr|upb|address_sorting|protobuf|re2|cares)\.so' |
  sort -u | sed 's/^/called_from_lib:/' >>"$supp"
export TSAN_OPTIONS="suppressions=$supp second_deadlock_stack=1 history_size=4 clear_shadow_mmap_threshold=4194304 ${TSAN_OPTIONS:-}"
if setarch "$(uname -m)" -R true 2>/dev/null; then
  setarch "$(uname -m)" -R "$bin" "$@"
else
  "$bin" "$@"
fi
