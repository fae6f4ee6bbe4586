// Points as screen-aligned quads of a fixed pixel size (instanced, 4 vertices each).
// Positions arrive relative to their chunk origin; the chunk offset is the origin minus the
// camera position, computed in double on the CPU (camera-relative rendering, seed 000 sec. 5),
// and view_proj holds the camera rotation only.

struct Frame {
  view_proj: mat4x4<f32>,
  viewport: vec2<f32>,
  point_size: f32,
  round_points: u32,
}

struct Chunk {
  offset: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> chunk: Chunk;

struct VertexOut {
  @builtin(position) clip: vec4<f32>,
  @location(0) color: vec4<f32>,
  @location(1) corner: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) position: vec3<f32>,
           @location(1) color: vec4<f32>) -> VertexOut {
  let corner = vec2<f32>(f32(vertex & 1u), f32(vertex >> 1u)) * 2.0 - 1.0;
  var clip = frame.view_proj * vec4<f32>(position + chunk.offset.xyz, 1.0);
  // Offset in clip space so the quad spans point_size pixels whatever the depth.
  clip = vec4<f32>(clip.xy + corner * frame.point_size / frame.viewport * clip.w, clip.zw);
  var out: VertexOut;
  out.clip = clip;
  out.color = color;
  out.corner = corner;
  return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
  if (frame.round_points != 0u && dot(in.corner, in.corner) > 1.0) {
    discard;
  }
  return vec4<f32>(in.color.rgb, 1.0);
}
