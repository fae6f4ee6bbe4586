// The compute rasterizer's attribute words (intensity, class, returns), one a point: read by the
// shading (compute_raster_shading.wgsl) and the filters (compute_raster_filter.wgsl).
@group(0) @binding(9) var<storage, read> attributes: array<u32>;
