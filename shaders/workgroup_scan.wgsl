// An inclusive prefix sum over a workgroup of 256 invocations (Hillis-Steele), two words at
// once: the splat sort's scatter scans four 16-bit counters packed in two words; a scan of one
// count passes (count, 0). Every invocation of the workgroup must call it; scan_words[255] holds
// the total afterwards (scan_total).
var<workgroup> scan_words: array<vec2<u32>, 256>;

fn inclusive_scan(lid: u32, v: vec2<u32>) -> vec2<u32> {
  scan_words[lid] = v;
  workgroupBarrier();
  for (var offset = 1u; offset < 256u; offset = offset << 1u) {
    var t = scan_words[lid];
    if (lid >= offset) {
      t = t + scan_words[lid - offset];
    }
    workgroupBarrier();
    scan_words[lid] = t;
    workgroupBarrier();
  }
  return scan_words[lid];
}

// The total of the last inclusive_scan (read before the workgroup scans again).
fn scan_total() -> vec2<u32> {
  return scan_words[255];
}
