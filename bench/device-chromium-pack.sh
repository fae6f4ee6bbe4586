#!/usr/bin/env bash
# Packs Debian's chromium for a GPU machine that has neither GTK nor NSS (bench/RESULTS.md, "The
# page on a GPU"): the browser's folder and every shared library ldd lists except glibc's own, in
# .devpkg/chromium-part-0{0,1,2,3}.xz (quarters of one tar.xz, 29 MiB each: a call's 64 MiB counts
# the working tree as a tar, about 25 MB, and what else the call carries), so that four calls to a
# warm machine can bring them; a runner (chromium-pkg/run) points LD_LIBRARY_PATH at the libraries.
#   bench/device-chromium-pack.sh
# On the device: keep each part under /tmp as it comes, then
#   cat /tmp/chromium-part-0? | xz -d | tar x -C /tmp && /tmp/chromium-pkg/run --version
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
grep -qx '/.devpkg/' "$root/.git/info/exclude" 2>/dev/null || echo '/.devpkg/' >>"$root/.git/info/exclude"
stage=$(mktemp -d)/chromium-pkg
mkdir -p "$stage/lib"
cp -a /usr/lib/chromium "$stage/chromium"
# Test-only Vulkan pieces the GPU run does not need.
rm -f "$stage"/chromium/libVkLayer_khronos_validation.so* "$stage"/chromium/libVkICD_mock_icd.so*
ldd /usr/lib/chromium/chromium | awk '/=> \// {print $3}' | while read -r lib; do
  case "$(basename "$lib")" in
    libc.so.*|libm.so.*|libdl.so.*|libpthread.so.*|librt.so.*|libresolv.so.*|ld-linux*) ;;
    *) cp -L "$lib" "$stage/lib/" ;;
  esac
done
cat >"$stage/run" <<'RUN'
#!/usr/bin/env bash
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
exec "$here/chromium/chromium" "$@"
RUN
chmod +x "$stage/run"
mkdir -p "$root/.devpkg"
tar -C "$(dirname "$stage")" -cf - chromium-pkg | xz -6 -T0 >"$root/.devpkg/chromium.tar.xz"
rm -rf "$(dirname "$stage")"
# Quarters of one stream.
rm -f "$root"/.devpkg/chromium-part-*
split -n 4 -d --additional-suffix=.xz "$root/.devpkg/chromium.tar.xz" "$root/.devpkg/chromium-part-"
rm "$root/.devpkg/chromium.tar.xz"
ls -la "$root"/.devpkg/chromium-part-*
