#!/usr/bin/env bash
# Installs every dependency of stipple from package registries on Debian 12 (bookworm),
# idempotently and quietly, then configures and builds build/ (Release with debug info).
#   scripts/setup.sh            install + build
#   scripts/setup.sh --deps     install only
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache keys on paths relative to the checkout, so a fresh clone elsewhere (CI) reuses the
# objects of earlier builds.
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
deps_only=0
[[ "${1:-}" == "--deps" ]] && deps_only=1
sudo_cmd=""
[[ $(id -u) -ne 0 ]] && sudo_cmd="sudo"
# Each line says the minutes and seconds since the start, so a log shows where the time goes.
log() { printf '[setup %d:%02d] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }

# ---- Debian packages -------------------------------------------------------------------
# Mesa 25 (lavapipe that Dawn accepts) comes from bookworm-backports; liblaszip-dev 3.5 from
# trixie, pinned so that nothing else is taken from trixie.
apt_pkgs=(build-essential cmake ninja-build ccache pkg-config git curl ca-certificates
  python3 python3-pip unzip xz-utils
  libglm-dev libglfw3-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libcurl4-openssl-dev libpng-dev libproj-dev proj-data libdraco-dev libmeshoptimizer-dev libzstd-dev
  libbrotli-dev libwebp-dev
  libgtest-dev libgmock-dev libbenchmark-dev libimgui-dev xvfb xauth
  libvulkan1 vulkan-tools clang-14 libclang-rt-14-dev clang-format nginx-light chromium)
# npm (for Dawn's package and the glTF validator) and venv (for py3dtiles) come from Debian
# only where the machine has none of its own: a Node.js or Python installed another way stays.
command -v npm >/dev/null || apt_pkgs+=(npm)
python3 -c 'import ensurepip, venv' 2>/dev/null || apt_pkgs+=(python3-venv)
need_apt=0
for p in "${apt_pkgs[@]}" liblaszip-dev mesa-vulkan-drivers; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || { need_apt=1; break; }
done
mesa_ver=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
[[ "$mesa_ver" == 25.* ]] || need_apt=1
if [[ $need_apt -eq 1 ]]; then
  log "installing Debian packages"
  $sudo_cmd tee /etc/apt/sources.list.d/stipple.sources >/dev/null <<'SRC'
Types: deb
URIs: http://deb.debian.org/debian
Suites: bookworm-backports trixie
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SRC
  $sudo_cmd tee /etc/apt/preferences.d/stipple >/dev/null <<'PIN'
Package: *
Pin: release n=trixie
Pin-Priority: 1

Package: liblaszip-dev liblaszip8
Pin: release n=trixie
Pin-Priority: 990
PIN
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get update -qq
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${apt_pkgs[@]}" >/dev/null
  $sudo_cmd apt-get install -y -qq --no-install-recommends -t bookworm-backports mesa-vulkan-drivers >/dev/null
  $sudo_cmd apt-get install -y -qq --no-install-recommends liblaszip-dev >/dev/null
fi

# ---- WebGPU implementations (into .deps/, ignored by git) -------------------------------
deps="$root/.deps"
mkdir -p "$deps"
wgpu_ver=0.32.0
if [[ ! -f "$deps/wgpu/lib/libwgpu_native-release.so" ]]; then
  log "fetching wgpu-native from the PyPI wheel wgpu==$wgpu_ver"
  tmp=$(mktemp -d)
  python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux_2_28_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    --python-version 3.11 -d "$tmp" "wgpu==$wgpu_ver" >/dev/null
  (cd "$tmp" && unzip -q -o ./*.whl 'wgpu/resources/*')
  mkdir -p "$deps/wgpu/include/webgpu" "$deps/wgpu/lib"
  cp "$tmp"/wgpu/resources/*.h "$deps/wgpu/include/webgpu/"
  cp "$tmp"/wgpu/resources/libwgpu_native-release.so "$deps/wgpu/lib/"
  rm -rf "$tmp"
fi
dawn_ver=0.1.7
if [[ ! -f "$deps/dawn/lib/libwebgpu_wrapper.so" ]]; then
  log "fetching Dawn from the npm package bun-webgpu-linux-x64@$dawn_ver"
  tmp=$(mktemp -d)
  (cd "$tmp" && npm pack --loglevel=error "bun-webgpu-linux-x64@$dawn_ver" >/dev/null && tar xzf ./*.tgz)
  mkdir -p "$deps/dawn/lib"
  cp "$(find "$tmp/package" -name 'libwebgpu_wrapper.so' | head -n1)" "$deps/dawn/lib/"
  rm -rf "$tmp"
fi
# ---- validators and peers for tests/benchmarks (into .deps/, never linked) ----------------
# Peers for the interop tests (tests/web; each skips without its package), never linked:
# Khronos glTF-Validator; CesiumJS, driven in Debian's chromium through puppeteer-core (no
# browser download); loaders.gl; Cesium's 3d-tiles-tools (its optional native sqlite module is
# not built: --ignore-scripts; the tests use none of it); potree-core with three.js; TypeScript's
# compiler, which checks a page's use of the web viewer's module against its declarations. The
# Cesium 3d-tiles-validator is not published on the npm registry we reach.
node_pkgs=(gltf-validator@2.0.0-dev.3.10 cesium@1.145.0 puppeteer-core@24.43.1
  @loaders.gl/core@4.5.4 @loaders.gl/3d-tiles@4.5.4 3d-tiles-tools@0.5.4 potree-core@2.0.15
  typescript@5.9.3)
if command -v npm >/dev/null; then
  missing=()
  for p in "${node_pkgs[@]}"; do
    [[ -f "$deps/node/node_modules/${p%@*}/package.json" ]] || missing+=("$p")
  done
  if [[ ${#missing[@]} -gt 0 ]]; then
    log "installing ${missing[*]} (npm) into .deps/node"
    mkdir -p "$deps/node"
    (cd "$deps/node" && npm install --silent --no-audit --no-fund --ignore-scripts --prefix . \
      "${missing[@]}" >/dev/null 2>&1) || log "npm packages not installed; the interop tests will skip"
  fi
fi
# py3dtiles for bench/tiler.sh; laspy and lazrs for tests/tools/write_copc.py (COPC test files).
if [[ ! -x "$deps/py3dtiles/bin/py3dtiles" ]]; then
  log "installing py3dtiles, laspy, lazrs (PyPI) into .deps/py3dtiles"
  python3 -m venv "$deps/py3dtiles" && "$deps/py3dtiles/bin/pip" install -q py3dtiles laspy lazrs >/dev/null ||
    log "py3dtiles not installed; bench/tiler.sh will skip it"
fi
if [[ -x "$deps/py3dtiles/bin/python" ]] && ! "$deps/py3dtiles/bin/python" -c 'import lazrs' 2>/dev/null; then
  "$deps/py3dtiles/bin/pip" install -q lazrs >/dev/null ||
    log "lazrs not installed; tests of written COPC files will skip"
fi
# The Python bindings' build and test environment (pyproject.toml; tests/python): nanobind and
# scikit-build-core build the extension, laspy + lazrs are what stipple.read is checked against,
# dask + distributed run stipple.dask. Reinstalled only when this list changes.
py_pkgs=(numpy==2.4.6 nanobind==3.1.0 scikit-build-core==1.1.2 pytest==9.2.0 laspy==2.7.0
  lazrs==0.8.2 dask==2026.8.0 distributed==2026.8.0)
if [[ "$(cat "$deps/python/.stipple-pkgs" 2>/dev/null)" != "${py_pkgs[*]}" ]]; then
  log "installing ${py_pkgs[*]} (PyPI) into .deps/python"
  { [[ -x "$deps/python/bin/python" ]] || python3 -m venv "$deps/python"; } &&
    "$deps/python/bin/pip" install -q --disable-pip-version-check "${py_pkgs[@]}" >/dev/null &&
    echo "${py_pkgs[*]}" >"$deps/python/.stipple-pkgs" ||
    log "Python packages not installed; the Python tests will skip"
fi
# The web build's toolchain (emscripten, binaryen, clang-19) into .deps/emscripten. Outside CI
# a failure here (a package gone from the mirror) costs the web viewer only, not the native
# build; CI must build it, since its test skips without it.
web_failed() {
  [[ -n "${CI:-}" ]] && exit 1
  log "the web viewer is not built ($1 failed); everything else is"
  web_ok=0
}
web_ok=1
"$root/scripts/build-web.sh" --deps || web_failed "its toolchain's install"
[[ $deps_only -eq 1 ]] && exit 0

# ---- configure and build ---------------------------------------------------------------
log "building build/ (Release with debug info)"
cmake -S "$root" -B "$root/build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
  -DSTIPPLE_WERROR="${CI:+ON}" >/dev/null
cmake --build "$root/build" -- -k 0 | { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
test -x "$root/build/stipple"
# The web viewer (build-web/): WebAssembly through ccache, like the native objects.
if [[ $web_ok -eq 1 ]]; then
  log "building build-web/ (the web viewer)"
  "$root/scripts/build-web.sh" || web_failed "its build"
fi
log "done: build/stipple$([[ $web_ok -eq 1 ]] && echo ", build-web/stipple.html")"
