#!/usr/bin/env bash
# Builds the web viewer (libstipple compiled to WebAssembly on the browser's WebGPU) into
# build-web/: stipple.html, stipple.js, stipple.wasm, the WGSL shaders and the page's shell.
# Installs its toolchain first, idempotently and quietly, from package registries:
#   - clang-19, lld-19, llvm-19 from Debian bookworm (installed);
#   - emscripten 3.1.69 and node-acorn from Debian trixie, and binaryen 108 from bookworm
#     (for wasm-emscripten-finalize), downloaded and unpacked into .deps/emscripten, never
#     installed (installing trixie's packages would upgrade libc);
#   - binaryen@120.0.0 from npm (the version emscripten 3.1.69 expects: wasm-opt and friends).
#   scripts/build-web.sh            toolchain + build
#   scripts/build-web.sh --deps     toolchain only
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
deps_only=0
[[ "${1:-}" == "--deps" ]] && deps_only=1
sudo_cmd=""
[[ $(id -u) -ne 0 ]] && sudo_cmd="sudo"
log() { printf '[build-web] %s\n' "$*"; }

# ---- clang/lld/llvm 19 (bookworm) ------------------------------------------------------
need_apt=0
for p in clang-19 lld-19 llvm-19; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need_apt=1
done
if [[ $need_apt -eq 1 ]]; then
  log "installing clang-19, lld-19, llvm-19"
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get install -y -qq --no-install-recommends clang-19 lld-19 llvm-19 >/dev/null 2>&1 ||
    { $sudo_cmd apt-get update -qq && $sudo_cmd apt-get install -y -qq --no-install-recommends clang-19 lld-19 llvm-19 >/dev/null; }
fi

# ---- emscripten, node-acorn, binaryen (unpacked into .deps/emscripten) -------------------
em_ver=3.1.69+dfsg-3
em="$root/.deps/emscripten"
if [[ ! -f "$em/.unpacked-$em_ver" ]]; then
  log "unpacking emscripten $em_ver, node-acorn (trixie) and binaryen 108 (bookworm) into .deps/emscripten"
  grep -rqs "trixie" /etc/apt/sources.list /etc/apt/sources.list.d/ || {
    echo "build-web: needs Debian trixie in the apt sources (scripts/setup.sh adds it, pinned at priority 1)" >&2
    exit 1
  }
  tmp=$(mktemp -d)
  (cd "$tmp" && apt-get download -qq "emscripten=$em_ver" "node-acorn/trixie" "binaryen=108-1" >/dev/null 2>&1) || {
    $sudo_cmd apt-get update -qq
    (cd "$tmp" && apt-get download -qq "emscripten=$em_ver" "node-acorn/trixie" "binaryen=108-1" >/dev/null)
  }
  rm -rf "$em" && mkdir -p "$em/root"
  for d in "$tmp"/*.deb; do dpkg -x "$d" "$em/root"; done
  rm -rf "$tmp"
  touch "$em/.unpacked-$em_ver"
fi
emroot="$em/root/usr/share/emscripten"
# node 20 does not search /usr/share/nodejs: emscripten's tools find acorn in its node_modules.
if [[ ! -e "$emroot/node_modules/acorn" ]]; then
  mkdir -p "$emroot/node_modules"
  ln -sfn "$em/root/usr/share/nodejs/acorn" "$emroot/node_modules/acorn"
fi
# binaryen 120 from npm (its wasm-opt etc. are JS); wasm-emscripten-finalize from binaryen 108.
bin_ver=120.0.0
if [[ ! -f "$em/binaryen/.installed-$bin_ver" ]]; then
  log "installing binaryen@$bin_ver from npm"
  rm -rf "$em/npm" && mkdir -p "$em/npm"
  npm install --silent --no-audit --no-fund --prefix "$em/npm" "binaryen@$bin_ver" >/dev/null
  mkdir -p "$em/binaryen/bin"
  for t in "$em/npm/node_modules/binaryen/bin/"*; do
    ln -sfn "$t" "$em/binaryen/bin/$(basename "$t")"
  done
  ln -sfn "$em/root/usr/bin/wasm-emscripten-finalize" "$em/binaryen/bin/wasm-emscripten-finalize"
  touch "$em/binaryen/.installed-$bin_ver"
fi
cat > "$em/config.py.tmp" <<CFG
LLVM_ROOT = '/usr/lib/llvm-19/bin'
BINARYEN_ROOT = '$em/binaryen'
NODE_JS = '$(command -v node)'
EMSCRIPTEN_ROOT = '$emroot'
CACHE = '$emroot/cache'
FROZEN_CACHE = True
CFG
cmp -s "$em/config.py.tmp" "$em/config.py" 2>/dev/null && rm "$em/config.py.tmp" || mv "$em/config.py.tmp" "$em/config.py"
export EM_CONFIG="$em/config.py"

[[ $deps_only -eq 1 ]] && exit 0

# ---- the web build ---------------------------------------------------------------------
# ccache launches emcc like any compiler (its objects are keyed on the emcc command line).
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
build="$root/build-web"
# build.ninja, not CMakeCache.txt: an interrupted first configure leaves only the cache.
# Warnings are errors in CI only, as in the native build (a newer clang must not stop a user).
if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_TOOLCHAIN_FILE="$emroot/cmake/Modules/Platform/Emscripten.cmake" \
    -DSTIPPLE_WERROR="${CI:+ON}" -DSTIPPLE_TESTS=OFF "${launcher[@]}" >/dev/null
fi
out=$(cmake --build "$build" -j"$(nproc)" 2>&1) || { printf '%s\n' "$out" >&2; exit 1; }
