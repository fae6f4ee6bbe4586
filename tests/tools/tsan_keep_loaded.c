// Preloaded into the GPU tests by scripts/tsan.sh: keeps the libraries named in
// STIPPLE_TSAN_KEEP_LOADED (colon-separated) loaded for the whole process.
//
// Why: tests/tsan.supp tells ThreadSanitizer to ignore what the Vulkan driver (lavapipe) does
// (called_from_lib), and ThreadSanitizer aborts the process when such a library is unloaded
// ("library ... that was matched against called_from_lib suppression ... is unloaded"). The
// Vulkan loader unloads the driver when the instance goes (Dawn and wgpu-native both release
// theirs with the context), so the second context a test creates would abort. A dlopen() with
// RTLD_NODELETE here holds it; RTLD_LOCAL keeps its symbols out of the global scope (preloading
// the driver itself with LD_PRELOAD made the Dawn tests crash in it, presumably on its exported
// SPIRV-Tools symbols taking the place of Dawn's).
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

__attribute__((constructor)) static void keep_loaded(void) {
  const char* list = getenv("STIPPLE_TSAN_KEEP_LOADED");
  if (!list) return;
  char names[4096];
  snprintf(names, sizeof names, "%s", list);
  char* save = NULL;
  for (char* name = strtok_r(names, ":", &save); name; name = strtok_r(NULL, ":", &save)) {
    if (!dlopen(name, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE))
      fprintf(stderr, "tsan_keep_loaded: %s\n", dlerror());
  }
}
