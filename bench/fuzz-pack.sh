#!/usr/bin/env bash
# bench/fuzz-pack.sh [TARGET...]: builds the libFuzzer targets as bench/fuzz.sh does (clang-14,
# AddressSanitizer + UndefinedBehaviorSanitizer, the parser modules with coverage: STIPPLE_FUZZ,
# in $STIPPLE_FUZZ_BUILD, default build-fuzz) and packs them for a campaign on another Linux
# x86-64 machine with no stipple build: the targets stripped of debug info, the shared
# libraries `ldd` lists (except glibc's own: libc, libm, ld-linux, libpthread, libdl, librt,
# libresolv: the other machine's glibc must be as new as this one's), PROJ's database, the corpus
# kept in tests/fuzz/corpus, the generated seeds (tests/fuzz/seeds), the heads of the LAS/LAZ files of
# ../shared/data, the regression inputs and the LeakSanitizer suppressions, with run.sh
# (bench/fuzz-run.sh). Default targets: every one in tests/fuzz/CMakeLists.txt; one that does not
# build is left out with a warning (FUZZ_PACK_STRICT=1: the script fails instead).
#   bench/fuzz-pack.sh                                 -> .devpkg/fuzz.tar.xz
#   FUZZ_PACK_OUT=/tmp/f.tar.xz bench/fuzz-pack.sh fuzz_las fuzz_tiles
#   STIPPLE_FUZZ_BUILD=build-fuzz-ub STIPPLE_FUZZ_SANITIZERS=undefined bench/fuzz-pack.sh fuzz_tileset
#     (UBSan and the standard library's bounds checks without ASan: several times the executions
#     for allocation-heavy parsers; replay its corpus under ASan after, bench/fuzz-replay.sh)
# On the other machine:
#   tar xJf fuzz.tar.xz && fuzz/run.sh -j 16 -t 3600
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
build=${STIPPLE_FUZZ_BUILD:-build-fuzz}
out=${FUZZ_PACK_OUT:-$root/.devpkg/fuzz.tar.xz}
jobs=${JOBS:-2}
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
if [[ $# -gt 0 ]]; then
  targets=("$@")
else
  mapfile -t targets < <(sed -n '/^set(STIPPLE_FUZZ_TARGETS/,/)/p' tests/fuzz/CMakeLists.txt |
    tr ' ()' '\n\n\n' | grep '^fuzz_')
fi

if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DSTIPPLE_SANITIZE=ON -DSTIPPLE_SANITIZERS="${STIPPLE_FUZZ_SANITIZERS:-address,undefined}" \
    -DSTIPPLE_FUZZ=ON >/dev/null
fi
start=$(date +%s)
built=()
for t in "${targets[@]}"; do
  if cmake --build "$build" --target "$t" -- -j"$jobs" >"$build/fuzz-pack-$t.log" 2>&1; then
    built+=("$t")
  else
    echo "fuzz-pack: $t did not build (log: $build/fuzz-pack-$t.log)" >&2
    [[ ${FUZZ_PACK_STRICT:-0} == 1 ]] && exit 1
  fi
done
echo "fuzz-pack: built ${#built[@]} of ${#targets[@]} targets in $(($(date +%s) - start)) s"
[[ ${#built[@]} -gt 0 ]] || exit 1

stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
pkg="$stage/fuzz"
mkdir -p "$pkg/bin" "$pkg/lib" "$pkg/corpus" "$pkg/seeds" "$pkg/las-heads" "$pkg/regressions" \
  "$pkg/proj"
declare -A libs=()
for t in "${built[@]}"; do
  objcopy --strip-debug "$build/tests/fuzz/$t" "$pkg/bin/$t"
  while read -r lib; do libs["$lib"]=1; done < <(ldd "$build/tests/fuzz/$t" |
    awk '$2 == "=>" && $3 ~ /^\// {print $3}' |
    grep -vE '/(libc|libm|libpthread|libdl|librt|libresolv|ld-linux[^/]*)\.so')
  if [[ -d tests/fuzz/corpus/$t ]]; then cp -r "tests/fuzz/corpus/$t" "$pkg/corpus/"; fi
  if [[ -d tests/fuzz/regressions/$t ]]; then cp -r "tests/fuzz/regressions/$t" "$pkg/regressions/"; fi
done
for lib in "${!libs[@]}"; do
  # The name the binaries ask for (a symlink's name), with the file's contents.
  objcopy --strip-debug "$(readlink -f "$lib")" "$pkg/lib/$(basename "$lib")"
done
find tests/fuzz/seeds -type f -exec cp {} "$pkg/seeds/" \;
if [[ -d ../shared/data ]]; then
  while IFS= read -r -d '' f; do
    head -c 65536 "$f" >"$pkg/las-heads/$(basename "$f")"
  done < <(find ../shared/data -type f \( -name '*.las' -o -name '*.laz' \) -print0)
fi
proj_db=$(pkg-config --variable=datadir proj 2>/dev/null || true)/proj.db
[[ -f "$proj_db" ]] || proj_db=/usr/share/proj/proj.db
[[ -f "$proj_db" ]] && cp "$proj_db" "$pkg/proj/"
cp tests/lsan.supp "$pkg/"
cp bench/fuzz-run.sh "$pkg/run.sh"
printf '%s\n' "${built[@]}" >"$pkg/targets"
{
  echo "stipple fuzz targets of $(git rev-parse --short HEAD 2>/dev/null || echo '?'), built $(date -u +%F)"
  echo "clang-14, -fsanitize=address,undefined, parser modules with -fsanitize=fuzzer-no-link"
  echo "glibc of the build machine: $(ldd --version | head -n1)"
  echo "run: fuzz/run.sh -j CORES -t SECONDS [TARGET...]"
} >"$pkg/README"
mkdir -p "$(dirname "$out")"
tar -C "$stage" -cf - fuzz | xz -T"$jobs" -6 >"$out.tmp"
mv "$out.tmp" "$out"
size=$(stat -c %s "$out")
echo "fuzz-pack: $out: $((size / 1048576)) MiB (${#built[@]} targets: ${built[*]}; ${#libs[@]} libraries)"
if [[ $size -gt $((40 * 1048576)) ]]; then
  echo "fuzz-pack: over 40 MiB" >&2
  exit 1
fi
