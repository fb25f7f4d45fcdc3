#!/bin/sh
# run.sh — runs every fuzz target of a PN_FUZZ build for SECONDS each on its corpus.
# usage: sh tests/fuzz/run.sh BUILD_DIR SECONDS
# The committed corpus (tests/fuzz/corpus/NAME) is read but never written: new inputs go to
# BUILD_DIR/fuzz-corpus/NAME, findings to BUILD_DIR/fuzz-artifacts/NAME/. Prints each target's
# executions and coverage (libFuzzer's final stats) and exits non-zero when any target found
# a crash, leak, timeout or sanitizer report.
set -u
here=$(cd "$(dirname "$0")" && pwd)
build=$1
seconds=$2
status=0
for name in scene ply exr png jpeg stb pfm photometry; do
  bin="$build/tests/fuzz/fuzz_$name"
  [ -x "$bin" ] || { echo "fuzz: $bin is missing (configure with -DPN_FUZZ=ON)"; exit 2; }
  work="$build/fuzz-corpus/$name"
  artifacts="$build/fuzz-artifacts/$name/"
  mkdir -p "$work" "$artifacts"
  dict=""
  [ -f "$here/$name.dict" ] && dict="-dict=$here/$name.dict"
  log="$build/fuzz-$name.log"
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
      -artifact_prefix="$artifacts" $dict "$work" "$here/corpus/$name" >"$log" 2>&1
  rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1)
  if [ $rc -eq 0 ]; then
    echo "fuzz_$name: ${execs:-?} executions in ${seconds} s, $cov, $ft: no finding"
  else
    echo "fuzz_$name: FINDING (exit $rc) after ${execs:-?} executions; see $log and $artifacts"
    grep -m 5 -E 'ERROR|SUMMARY|runtime error' "$log"
    status=1
  fi
done
exit $status
