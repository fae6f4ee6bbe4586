// The read bound of `stipple bench bandwidth` and `bench raster`: what a compute shader reaches
// reading a large buffer. Every thread reads 16-byte words in a grid-stride loop and XORs them;
// the result is written only if it equals a value it cannot plausibly take, so the reads stay
// and almost nothing is written. fill_main first writes a hash of each word's index (timing
// reads of zeros can flatter them).

@group(0) @binding(0) var<storage, read_write> data: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read_write> sink: array<u32>;

fn hash(x_in: u32) -> u32 {
  var x = x_in * 0x9e3779b1u;
  x ^= x >> 15u;
  x *= 0x85ebca77u;
  return x ^ (x >> 13u);
}

@compute @workgroup_size(256)
fn fill_main(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
  let total = arrayLength(&data);
  let threads = groups.x * 256u;
  for (var i = gid.x; i < total; i += threads) {
    data[i] = vec4<u32>(hash(4u * i), hash(4u * i + 1u), hash(4u * i + 2u), hash(4u * i + 3u));
  }
}

@compute @workgroup_size(256)
fn read_main(@builtin(global_invocation_id) gid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
  let total = arrayLength(&data);
  let threads = groups.x * 256u;
  var acc = vec4<u32>(0u);
  for (var i = gid.x; i < total; i += threads) {
    acc ^= data[i];
  }
  let r = acc.x ^ acc.y ^ acc.z ^ acc.w;
  if (r == 0x12345678u) {
    sink[gid.x & 1023u] = r;
  }
}
