#!/usr/bin/env bash
# Builds the web viewer (libstipple compiled to WebAssembly on the browser's WebGPU) into
# build-web/: stipple.html, stipple.js, stipple.wasm, the WGSL shaders and the page's shell.
# Installs its toolchain first, idempotently and quietly, from package registries:
#   - clang-19, lld-19, llvm-19 from Debian bookworm (installed);
#   - emscripten 3.1.69 and node-acorn from Debian trixie, and binaryen 108 from bookworm
#     (for wasm-emscripten-finalize), downloaded and unpacked into .deps/emscripten, never
#     installed (installing trixie's packages would upgrade libc);
#   - binaryen@120.0.0 from npm (the version emscripten 3.1.69 expects: wasm-opt and friends);
#   - LASzip 3.5.0 (the native build's Debian liblaszip) compiled to WebAssembly from Debian
#     trixie's orig source tarball (checksum as in trixie's Sources index) into .deps/laszip-wasm.
#   scripts/build-web.sh            toolchain + build
#   scripts/build-web.sh --deps     toolchain and LASzip only
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

# ---- LASzip 3.5.0 for WebAssembly (.deps/laszip-wasm) ------------------------------------
# The same LASzip as the native build's (Debian's liblaszip 3.5.0), from Debian's upstream
# tarball: the .dsc of trixie's 3.5.0-2 is gone from the mirror, the orig tarball is not. Static,
# with the web build's threads and native WebAssembly exceptions (cmake/web.cmake), or it would
# not link with libstipple.
lz_ver=3.5.0
lz_sha256=b95adc812795b373d418ee7851938131bc33a54c452924183fe72597b5283907
lz="$root/.deps/laszip-wasm"
lz_flags="-pthread -fwasm-exceptions"
if [[ ! -f "$lz/.built-$lz_ver" ]]; then
  tarball="$root/.deps/laszip_$lz_ver.orig.tar.xz"
  if ! echo "$lz_sha256  $tarball" | sha256sum -c --status 2>/dev/null; then
    log "downloading laszip_$lz_ver.orig.tar.xz (Debian trixie's source)"
    src=$(mktemp -d)
    echo "deb-src http://deb.debian.org/debian trixie main" > "$src/sources.list"
    mkdir -p "$src/lists/partial"
    apt_src=(-o Dir::Etc::SourceList="$src/sources.list" -o Dir::Etc::SourceParts=/dev/null
             -o Dir::State::Lists="$src/lists" -o Debug::NoLocking=1)
    apt-get -qq "${apt_src[@]}" update >/dev/null 2>&1 || true
    # --download-only fails on the missing .dsc after the tarball is in: the checksum decides.
    (cd "$src" && apt-get -qq "${apt_src[@]}" source --download-only "laszip=$lz_ver-2" >/dev/null 2>&1) || true
    [[ -f "$src/laszip_$lz_ver.orig.tar.xz" ]] && mv "$src/laszip_$lz_ver.orig.tar.xz" "$tarball"
    rm -rf "$src"
    echo "$lz_sha256  $tarball" | sha256sum -c --status 2>/dev/null || {
      echo "build-web: laszip_$lz_ver.orig.tar.xz is missing or its checksum differs" >&2
      exit 1
    }
  fi
  log "building LASzip $lz_ver for WebAssembly into .deps/laszip-wasm"
  tmp=$(mktemp -d)
  tar xf "$tarball" -C "$tmp"
  cmake -S "$tmp/LASzip-$lz_ver" -B "$tmp/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_TOOLCHAIN_FILE="$emroot/cmake/Modules/Platform/Emscripten.cmake" \
    -DLASZIP_BUILD_STATIC=ON -DCMAKE_C_FLAGS="$lz_flags" -DCMAKE_CXX_FLAGS="$lz_flags" \
    -DCMAKE_INSTALL_PREFIX="$lz" >/dev/null
  out=$(cmake --build "$tmp/build" -j"$(nproc)" --target laszip 2>&1) || { printf '%s\n' "$out" >&2; exit 1; }
  rm -rf "$lz" && mkdir -p "$lz/lib" "$lz/include/laszip"
  cp "$(find "$tmp/build" -name liblaszip.a | head -n1)" "$lz/lib/"
  cp "$tmp/LASzip-$lz_ver/include/laszip/laszip_api.h" \
    "$tmp/build/include/laszip/laszip_api_version.h" "$lz/include/laszip/"
  rm -rf "$tmp"
  touch "$lz/.built-$lz_ver"
fi


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
