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
#     trixie's orig source tarball (checksum as in trixie's Sources index) into .deps/laszip-wasm;
#   - the tile decoders, the native build's Debian bookworm versions compiled to WebAssembly from
#     their orig source tarballs (checksums as in bookworm's Sources index), decoders only:
#     meshoptimizer 0.18 (.deps/meshopt-wasm), Draco 1.5.5 (.deps/draco-wasm), zstd 1.5.4
#     (.deps/zstd-wasm), Brotli 1.0.9 (.deps/brotli-wasm).
#   scripts/build-web.sh            toolchain + build
#   scripts/build-web.sh --deps     toolchain, LASzip and the decoders only
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
deps_only=0
[[ "${1:-}" == "--deps" ]] && deps_only=1
sudo_cmd=""
[[ $(id -u) -ne 0 ]] && sudo_cmd="sudo"
log() { printf '[build-web %d:%02d] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }

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

# ---- Debian orig source tarballs ------------------------------------------------------------
# fetch_orig SUITE SOURCE=VERSION TARBALL SHA256: Debian's upstream tarball of a source package
# into .deps/ (kept: a rebuild does not download again), through apt with a private source list
# (the system's apt state is left alone). The checksum, as in the suite's Sources index, decides.
fetch_orig() {
  local suite=$1 spec=$2 name=$3 sha=$4
  local tarball="$root/.deps/$name"
  echo "$sha  $tarball" | sha256sum -c --status 2>/dev/null && return 0
  log "downloading $name (Debian $suite's source)"
  local src
  src=$(mktemp -d)
  echo "deb-src http://deb.debian.org/debian $suite main" > "$src/sources.list"
  mkdir -p "$src/lists/partial"
  local apt_src=(-o Dir::Etc::SourceList="$src/sources.list" -o Dir::Etc::SourceParts=/dev/null
                 -o Dir::State::Lists="$src/lists" -o Debug::NoLocking=1)
  apt-get -qq "${apt_src[@]}" update >/dev/null 2>&1 || true
  # --download-only fails where the .dsc is gone from the mirror (trixie's laszip) after the
  # tarball is in: the checksum decides.
  (cd "$src" && apt-get -qq "${apt_src[@]}" source --download-only "$spec" >/dev/null 2>&1) || true
  [[ -f "$src/$name" ]] && mv "$src/$name" "$tarball"
  rm -rf "$src"
  echo "$sha  $tarball" | sha256sum -c --status 2>/dev/null || {
    echo "build-web: $name is missing or its checksum differs" >&2
    exit 1
  }
}

# em_lib OUT.a DIR FLAGS... -- SOURCES...: compiles SOURCES (relative to DIR) with emcc, with the
# web build's threads and native WebAssembly exceptions (cmake/web.cmake, or they would not link
# with libstipple), through a throwaway ninja file (a core each), and archives them; quiet unless
# a compile fails.
em_lib() {
  local out=$1 dir=$2 flags=() f b
  shift 2
  while [[ $1 != -- ]]; do flags+=("$1"); shift; done
  shift
  b=$(mktemp -d)
  {
    echo "rule cc"
    echo "  command = $emroot/emcc -O2 -pthread -fwasm-exceptions ${flags[*]} -c \$in -o \$out"
    for f in "$@"; do echo "build $b/${f//\//_}.o: cc $dir/$f"; done
  } > "$b/build.ninja"
  local log
  log=$(ninja -C "$b" -j "$(nproc)" 2>&1) || { printf '%s\n' "$log" >&2; exit 1; }
  rm -f "$out"
  "$emroot/emar" rcs "$out" "$b"/*.o
  rm -rf "$b"
}

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
  fetch_orig trixie "laszip=$lz_ver-2" "laszip_$lz_ver.orig.tar.xz" "$lz_sha256"
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


# ---- Tile decoders for WebAssembly (.deps/*-wasm) -------------------------------------------
# The native build's Debian bookworm versions, from their upstream tarballs, so the web io module
# runs the same decoding code: Draco pnts and meshopt glb tiles (`stipple tile --compress`),
# zstandard EPT nodes, BROTLI Potree 2.0 nodes. Decoders only, compiled straight from their
# source files (not through the projects' own builds, which would build the encoders, tools and,
# for Draco under emscripten, its JavaScript decoder): a fraction of the CPU time, in CI too.
dec_ver=1  # the recipes below: bump to rebuild every decoder

# wasm_decoder DIR VERSION SOURCE=DEBVERSION TARBALL SHA256 WHAT RECIPE [TAR_ARGS...]: unless
# .deps/DIR/.built-VERSION-$dec_ver is there, fetches Debian's TARBALL, unpacks TAR_ARGS of it
# (all of it without) into a scratch folder, empties .deps/DIR (lib/ and include/ made) and runs
# RECIPE SCRATCH DIR_PATH, which compiles the decoder into DIR_PATH/lib and copies its headers;
# the stamp is written once it has.
wasm_decoder() {
  local dir=$1 ver=$2 spec=$3 tarball=$4 sha=$5 what=$6 recipe=$7
  shift 7
  local out="$root/.deps/$dir" tmp
  [[ -f "$out/.built-$ver-$dec_ver" ]] && return 0
  fetch_orig bookworm "$spec" "$tarball" "$sha"
  log "building $what for WebAssembly into .deps/$dir"
  tmp=$(mktemp -d)
  tar xf "$root/.deps/$tarball" -C "$tmp" "$@"
  rm -rf "$out" && mkdir -p "$out/lib" "$out/include"
  "$recipe" "$tmp" "$out"
  rm -rf "$tmp"
  touch "$out/.built-$ver-$dec_ver"
}

mo_ver=0.18
meshopt_recipe() {
  local s="$1/meshoptimizer-$mo_ver/src"
  em_lib "$2/lib/libmeshoptimizer.a" "$s" -- vertexcodec.cpp vertexfilter.cpp indexcodec.cpp
  cp "$s/meshoptimizer.h" "$2/include/"
}
wasm_decoder meshopt-wasm "$mo_ver" "meshoptimizer=$mo_ver+dfsg-2" "meshoptimizer_$mo_ver+dfsg.orig.tar.xz" \
  881ea2cc687f1fef5ce70484e0ca6504e13856dd856677749f3763bc685956d3 \
  "meshoptimizer $mo_ver (vertex and index codecs)" meshopt_recipe

# Draco: the point cloud decoder (3DTILES_draco_point_compression holds point clouds, never
# meshes), with the native package's features less the mesh ones (draco_features.h).
dr_ver=1.5.5
draco_recipe() {
  local s dr=$2
  s=$(echo "$1"/*/src)
  mkdir -p "$dr/include/draco"
  {
    echo "#ifndef DRACO_FEATURES_H_"
    echo "#define DRACO_FEATURES_H_"
    for f in POINT_CLOUD_COMPRESSION NORMAL_ENCODING BACKWARDS_COMPATIBILITY \
      ATTRIBUTE_INDICES_DEDUPLICATION ATTRIBUTE_VALUES_DEDUPLICATION; do
      echo "#define DRACO_${f}_SUPPORTED"
    done
    echo "#endif"
  } > "$dr/include/draco/draco_features.h"
  em_lib "$dr/lib/libdraco.a" "$s/draco" -I"$s" -I"$dr/include" -- \
    attributes/{attribute_octahedron_transform,attribute_quantization_transform}.cc \
    attributes/{attribute_transform,geometry_attribute,point_attribute}.cc \
    compression/attributes/{attributes_decoder,kd_tree_attributes_decoder}.cc \
    compression/attributes/sequential_{attribute_decoder,attribute_decoders_controller}.cc \
    compression/attributes/sequential_{integer,normal,quantization}_attribute_decoder.cc \
    compression/bit_coders/{adaptive_rans,direct,rans,symbol}_bit_decoder.cc \
    compression/{decode,draco_compression_options}.cc compression/entropy/symbol_decoding.cc \
    compression/point_cloud/point_cloud_{decoder,kd_tree_decoder,sequential_decoder}.cc \
    compression/point_cloud/algorithms/dynamic_integer_points_kd_tree_decoder.cc \
    compression/point_cloud/algorithms/float_points_tree_decoder.cc \
    core/{bit_utils,bounding_box,data_buffer,decoder_buffer,divide,draco_types}.cc \
    core/{hash_utils,options,quantization_utils}.cc \
    metadata/{metadata_decoder,geometry_metadata,metadata}.cc point_cloud/point_cloud.cc
  (cd "$s" && find draco -name '*.h' -exec cp --parents {} "$dr/include/" \;)
}
# The sources only: the 63 MB of test data stay in the tarball.
wasm_decoder draco-wasm "$dr_ver" "draco=$dr_ver+dfsg-2" "draco_$dr_ver+dfsg.orig.tar.xz" \
  0d4ff5b218a2f9d836c6f44202918402591407b5f59a5103ec288c5600ab087f \
  "the Draco $dr_ver point cloud decoder" draco_recipe --wildcards '*/src/draco'

zs_ver=1.5.4
zstd_recipe() {
  local s="$1/zstd-$zs_ver/lib"
  # No x86 assembly (huf_decompress_amd64.S), no multithreading (a decoder needs none).
  em_lib "$2/lib/libzstd.a" "$s" -DZSTD_DISABLE_ASM -- \
    common/{debug,entropy_common,error_private,fse_decompress,xxhash,zstd_common}.c \
    decompress/{huf_decompress,zstd_ddict,zstd_decompress,zstd_decompress_block}.c
  cp "$s/zstd.h" "$s/zstd_errors.h" "$2/include/"
}
wasm_decoder zstd-wasm "$zs_ver" "libzstd=$zs_ver+dfsg2-5" "libzstd_$zs_ver+dfsg2.orig.tar.xz" \
  8cf4bbb65e77ec348d052c8d6230eba66d435bddf64c8b5be2fcb16880c19953 \
  "the zstd $zs_ver decoder" zstd_recipe "zstd-$zs_ver/lib"

br_ver=1.0.9
brotli_recipe() {
  local s="$1/brotli-$br_ver/c"
  em_lib "$2/lib/libbrotlidec.a" "$s" -I"$s/include" -- \
    common/{constants,context,dictionary,platform,transform}.c dec/{bit_reader,decode,huffman,state}.c
  cp -r "$s/include/brotli" "$2/include/"
}
wasm_decoder brotli-wasm "$br_ver" "brotli=$br_ver-2" "brotli_$br_ver.orig.tar.gz" \
  f9e8d81d0405ba66d181529af42a3354f838c939095ff99930da6aa9cdf6fe46 \
  "the Brotli $br_ver decoder" brotli_recipe "brotli-$br_ver/c"

[[ $deps_only -eq 1 ]] && exit 0

# ---- the web build ---------------------------------------------------------------------
# ccache launches emcc like any compiler (its objects are keyed on the emcc command line).
log "compiling libstipple and the viewer to WebAssembly (build-web/)"
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
log "done"
