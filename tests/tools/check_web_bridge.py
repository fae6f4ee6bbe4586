#!/usr/bin/env python3
"""The browser's WebGPU bridge (src/renderer/src/webgpu_web.cpp) answers every WebGPU function
the library and the page call: a call it lacks aborts the page at run time ("the loaded WebGPU
implementation has no wgpuX"), and only where that code runs (the compute rasterizer's second
frame on a GPU asked for wgpuBufferGetSize). Functions the code calls only where
has_proc("wgpuX") says the implementation has them (wgpu-native's and Dawn's extensions) are
exempt. Prints what is missing and exits 1.

  check_web_bridge.py SOURCE_DIR"""
import glob
import os
import re
import sys

root = sys.argv[1]
bridge = os.path.join(root, 'src/renderer/src/webgpu_web.cpp')
entries = {'wgpu' + n for n in re.findall(r'STIPPLE_ENTRY\(\s*(\w+)\s*\)', open(bridge).read())}
if len(entries) < 50:
    sys.exit(f'{bridge}: only {len(entries)} entries found: has the table changed form?')
called, guarded = {}, set()
for f in sorted(glob.glob(os.path.join(root, 'src/**/*.[ch]pp'), recursive=True) +
                glob.glob(os.path.join(root, 'web/*.[ch]pp'))):
    if os.path.samefile(f, bridge):
        continue
    text = open(f, encoding='utf-8').read()
    guarded |= set(re.findall(r'has_proc\("(wgpu\w+)"\)', text))
    for name in re.findall(r'\b(wgpu[A-Z]\w*)\s*\(', text):
        called.setdefault(name, os.path.relpath(f, root))
missing = sorted(n for n in called if n not in entries and n not in guarded)
for n in missing:
    print(f'{bridge}: no entry for {n}, which {called[n]} calls')
print(f'{len(called)} WebGPU functions called, {len(entries)} bridged, {len(guarded)} behind has_proc')
sys.exit(1 if missing else 0)
