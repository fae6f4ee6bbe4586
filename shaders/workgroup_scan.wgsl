// An inclusive prefix sum over a workgroup of 256 invocations (Hillis-Steele), two words at
// once: the splat sort's scatter scans four 16-bit counters packed in two words; a scan of one
// count passes (count, 0). Every invocation of the workgroup must call it; scan_total() holds
// the total afterwards.
//
// The steps read one half of scan_words and write the other, so a step needs one barrier, not
// two (a step's writes never meet its reads): 9 barriers a scan instead of 17, for 4 KB of
// workgroup memory instead of 2.
var<workgroup> scan_words: array<vec2<u32>, 512>;

fn inclusive_scan(lid: u32, v: vec2<u32>) -> vec2<u32> {
  scan_words[lid] = v;
  workgroupBarrier();
  var sum = v;
  var half = 0u;  // the half the last step wrote
  for (var offset = 1u; offset < 256u; offset = offset << 1u) {
    if (lid >= offset) {
      sum = sum + scan_words[half + lid - offset];
    }
    half = 256u - half;
    scan_words[half + lid] = sum;
    workgroupBarrier();
  }
  return sum;
}

// The total of the last inclusive_scan (read before the workgroup scans again). Its eight steps
// end in the first half.
fn scan_total() -> vec2<u32> {
  return scan_words[255];
}
