// Dear ImGui draw lists: 2D triangles in window pixels, textured by the font atlas, tinted by
// the vertex colour, alpha-blended over the frame.
struct Uniforms {
  scale: vec2f,      // pixels to clip space
  translate: vec2f,
};
@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(1) var atlas_sampler: sampler;
@group(0) @binding(2) var atlas: texture_2d<f32>;

struct VertexIn {
  @location(0) position: vec2f,
  @location(1) uv: vec2f,
  @location(2) color: vec4f,
};
struct VertexOut {
  @builtin(position) position: vec4f,
  @location(0) uv: vec2f,
  @location(1) color: vec4f,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
  var out: VertexOut;
  out.position = vec4f(v.position * u.scale + u.translate, 0.0, 1.0);
  out.uv = v.uv;
  out.color = v.color;
  return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4f {
  return in.color * textureSample(atlas, atlas_sampler, in.uv);
}
