// GPU buffer compaction of the virtual memory system (seed 002, III-C1, Fig. 6): rebuilds the
// point buffers of the next frame from those of the previous one and the new points. The
// compaction info is a list of jobs sorted by destination that together cover [0, total): each
// copies `count` points to `dst` from `src`, in the previous frame's buffers or (fresh == 1) in
// the new points. One thread per destination point, so no thread idles however the points are
// spread over pointlets (the seed names idle threads in compaction as its main bottleneck); a
// workgroup's 256 destinations find their jobs by binary search between the first jobs of this
// workgroup and the next, which the CPU puts in front of the jobs. Positions (three words) and
// the colour and attribute words are separate entry points: each binds at most eight storage
// buffers. A new point is five words in `fresh`: coarse, medium, fine, colour, attributes.

struct Params {
  total: u32,    // points in the next frame's buffers
  jobs: u32,
  row: u32,      // threads per row of the 2D dispatch
  jobs_at: u32,  // where the jobs start in `info` (u32s); before them, per workgroup, its first job
}

struct Job {
  dst: u32,
  src: u32,
  count: u32,
  fresh: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> info: array<u32>;
@group(0) @binding(2) var<storage, read> fresh: array<u32>;
@group(0) @binding(3) var<storage, read> src_a: array<u32>;
@group(0) @binding(4) var<storage, read> src_b: array<u32>;
@group(0) @binding(5) var<storage, read> src_c: array<u32>;
@group(0) @binding(6) var<storage, read_write> dst_a: array<u32>;
@group(0) @binding(7) var<storage, read_write> dst_b: array<u32>;
@group(0) @binding(8) var<storage, read_write> dst_c: array<u32>;

const WORKGROUP: u32 = 256u;

fn job_dst(j: u32) -> u32 {
  return info[params.jobs_at + 4u * j];
}

// The job holding destination `index`: the last job whose dst <= index, among those that touch
// the workgroup's range.
fn find_job(index: u32) -> Job {
  let block = index / WORKGROUP;
  var lo = info[block];
  var hi = min(info[block + 1u] + 1u, params.jobs);
  while (hi - lo > 1u) {
    let mid = (lo + hi) / 2u;
    if (job_dst(mid) <= index) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  let at = params.jobs_at + 4u * lo;
  return Job(info[at], info[at + 1u], info[at + 2u], info[at + 3u]);
}

// Where destination `index` copies from: index `at` of the new points (fresh) or of the previous
// frame's buffers.
struct Source {
  at: u32,
  fresh: bool,
}

fn source_of(index: u32) -> Source {
  let job = find_job(index);
  return Source(job.src + (index - job.dst), job.fresh != 0u);
}

fn destination(group: vec3<u32>, lid: u32) -> u32 {
  return group.y * params.row + group.x * WORKGROUP + lid;
}

@compute @workgroup_size(256)
fn compact_positions(@builtin(workgroup_id) group: vec3<u32>,
                     @builtin(local_invocation_index) lid: u32) {
  let index = destination(group, lid);
  if (index >= params.total) {
    return;
  }
  let s = source_of(index);
  if (s.fresh) {
    let at = s.at * 5u;
    dst_a[index] = fresh[at];
    dst_b[index] = fresh[at + 1u];
    dst_c[index] = fresh[at + 2u];
  } else {
    dst_a[index] = src_a[s.at];
    dst_b[index] = src_b[s.at];
    dst_c[index] = src_c[s.at];
  }
}

@compute @workgroup_size(256)
fn compact_colors(@builtin(workgroup_id) group: vec3<u32>,
                  @builtin(local_invocation_index) lid: u32) {
  let index = destination(group, lid);
  if (index >= params.total) {
    return;
  }
  let s = source_of(index);
  if (s.fresh) {
    dst_a[index] = fresh[s.at * 5u + 3u];
    dst_b[index] = fresh[s.at * 5u + 4u];
  } else {
    dst_a[index] = src_a[s.at];
    dst_b[index] = src_b[s.at];
  }
}
