#!/usr/bin/env bash
# Packs what a GPU machine without this project's build tools needs to run `stipple` (for the
# H200 measurements in bench/RESULTS.md): the stripped binary, every shared library ldd lists
# except glibc's own, the WebGPU implementations from .deps/, and a runner that points
# LD_LIBRARY_PATH at them. Output: .devpkg/stipple.tar.xz (git-ignored via .git/info/exclude).
#   bench/device-pack.sh [STIPPLE] [NAME]     (NAME: stipple by default; another binary beside it)
# On the device (xz: no zstd there): tar xf .devpkg/stipple.tar.xz -C /tmp && /tmp/stipple-pkg/run bench raster ...
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin=${1:-$root/build/stipple}
name=${2:-stipple}
# (.gitignore lists it too; a worktree's .git is a file, without info/)
if [ -d "$root/.git/info" ]; then
  grep -qx '/.devpkg/' "$root/.git/info/exclude" 2>/dev/null || echo '/.devpkg/' >>"$root/.git/info/exclude"
fi
stage=$(mktemp -d)/$name-pkg
mkdir -p "$stage/lib"
strip -o "$stage/stipple" "$bin"
# glibc, the loader and libstdc++'s runtime peers stay the machine's own only when they are at
# least as new as ours: carry libstdc++ and libgcc_s too (a CUDA image may be older).
ldd "$bin" | awk '/=> \// {print $3}' | while read -r lib; do
  case "$(basename "$lib")" in
    libc.so.*|libm.so.*|libdl.so.*|libpthread.so.*|librt.so.*|libresolv.so.*|ld-linux*) ;;
    *) cp -L "$lib" "$stage/lib/" ;;
  esac
done
cp "$root/.deps/wgpu/lib/libwgpu_native-release.so" "$root/.deps/dawn/lib/libwebgpu_wrapper.so" \
  "$stage/lib/"
cat >"$stage/run" <<'RUN'
#!/usr/bin/env bash
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export STIPPLE_WGPU_LIBRARY="$here/lib/libwgpu_native-release.so"
export STIPPLE_DAWN_LIBRARY="$here/lib/libwebgpu_wrapper.so"
exec "$here/stipple" "$@"
RUN
chmod +x "$stage/run"
mkdir -p "$root/.devpkg"
tar -C "$(dirname "$stage")" -cf - "$name-pkg" | xz -6 -T0 >"$root/.devpkg/$name.tar.xz"
rm -rf "$(dirname "$stage")"
ls -la "$root/.devpkg/$name.tar.xz"
