// `stipple bench`: micro-benchmarks that reproduce the seed paper's measurements.
//
// `bench suballoc` (seed 000, section 3.5, Tables 2-3): N vertex buffers (Vertex|CopyDst) with
// sizes uniform in [min, max] KiB are allocated, then all freed, (a) directly with
// wgpuDeviceCreateBuffer / wgpuBufferDestroy + wgpuBufferRelease and (b) with the suballocator
// at several page sizes. Each operation is timed on the CPU with steady_clock.
//
// What "alloc" measures: like the paper, the createBuffer call only. On Vulkan both Dawn and
// wgpu-native create the VkBuffer and bind device memory inside createBuffer (so the buffer is
// real, not a promise), but zero-initialisation is deferred to first use. --touch writes 4 bytes
// into every allocation after the timed loop (forcing that first use and checking the buffers
// work); it is off by default because it makes the driver clear every buffer.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/suballocator.hpp"

namespace stipple::app {
namespace {

using Clock = std::chrono::steady_clock;

struct SuballocArgs {
  uint32_t count = 10'000;
  uint32_t min_kb = 128, max_kb = 1024;
  std::vector<uint32_t> page_mb = {16, 32, 64, 128};
  std::string backend;
  std::string json;
  uint32_t seed = 1;
  std::string free_order = "alloc";
  bool touch = false;
  uint32_t repeat = 1;
};

constexpr WGPUBufferUsage kUsage = WGPUBufferUsage_Vertex | WGPUBufferUsage_CopyDst;
constexpr uint32_t kPollEvery = 256;  // operations between (untimed) device polls

double elapsed_ns(Clock::time_point t0, Clock::time_point t1) {
  return std::chrono::duration<double, std::nano>(t1 - t0).count();
}

struct OpTimes {
  double mean = 0, p50 = 0, p99 = 0, max = 0;  // nanoseconds
};

OpTimes summarise(std::vector<double> ns) {
  OpTimes t;
  if (ns.empty()) return t;
  t.mean = std::accumulate(ns.begin(), ns.end(), 0.0) / double(ns.size());
  std::sort(ns.begin(), ns.end());
  t.p50 = ns[ns.size() / 2];
  t.p99 = ns[std::min(ns.size() - 1, ns.size() * 99 / 100)];
  t.max = ns.back();
  return t;
}

// Median over runs of each statistic of the per-run operation times.
template <typename Run, typename Get>
OpTimes median_of(const std::vector<Run>& runs, Get get) {
  auto median_field = [&](double OpTimes::*field) {
    std::vector<double> v;
    for (const Run& r : runs) v.push_back(get(r).*field);
    return median(std::move(v));
  };
  return {median_field(&OpTimes::mean), median_field(&OpTimes::p50), median_field(&OpTimes::p99),
          median_field(&OpTimes::max)};
}

nlohmann::json to_json(const OpTimes& t) {
  return {{"mean_ns", t.mean}, {"p50_ns", t.p50}, {"p99_ns", t.p99}, {"max_ns", t.max}};
}

// Mean cost of one steady_clock::now() pair: included in every per-operation time.
double clock_overhead_ns() {
  const int n = 100'000;
  double total = 0;
  for (int i = 0; i < n; ++i) {
    auto t0 = Clock::now();
    auto t1 = Clock::now();
    total += elapsed_ns(t0, t1);
  }
  return total / n;
}

// Writes 4 bytes at `offset` of every buffer and waits: forces lazily initialised memory into
// use and surfaces errors of buffers that were not really created.
void touch(gpu::Context& ctx, const std::vector<WGPUBuffer>& buffers,
           const std::vector<uint64_t>& offsets) {
  const uint32_t word = 0x5717u;
  for (size_t i = 0; i < buffers.size(); ++i) {
    gpu::write_buffer(ctx, buffers[i], offsets[i], word);
    if (i % kPollEvery == kPollEvery - 1) ctx.poll(false);
  }
  ctx.wait_idle();
  ctx.check("writing into every buffer (--touch)");
}

std::vector<uint32_t> free_order(const SuballocArgs& args, std::mt19937_64& rng) {
  std::vector<uint32_t> order(args.count);
  std::iota(order.begin(), order.end(), 0u);
  if (args.free_order == "reverse") std::reverse(order.begin(), order.end());
  if (args.free_order == "random") std::shuffle(order.begin(), order.end(), rng);
  return order;
}

struct DirectResult {
  OpTimes alloc, free;
};

DirectResult bench_direct(gpu::Context& ctx, const SuballocArgs& args,
                          const std::vector<uint64_t>& sizes, const std::vector<uint32_t>& order) {
  std::vector<WGPUBuffer> buffers(sizes.size());
  std::vector<double> alloc_ns(sizes.size()), free_ns(sizes.size());
  WGPUBufferDescriptor desc = WGPU_BUFFER_DESCRIPTOR_INIT;
  desc.usage = kUsage;
  for (size_t i = 0; i < sizes.size(); ++i) {
    desc.size = sizes[i];
    auto t0 = Clock::now();
    buffers[i] = wgpuDeviceCreateBuffer(ctx.device.get(), &desc);
    auto t1 = Clock::now();
    alloc_ns[i] = elapsed_ns(t0, t1);
    if (!buffers[i]) fail("bench: createBuffer of {} bytes returned null", sizes[i]);
    if (i % kPollEvery == kPollEvery - 1) ctx.poll(false);
  }
  ctx.poll(false);
  ctx.check("creating buffers directly");
  if (args.touch) touch(ctx, buffers, std::vector<uint64_t>(buffers.size(), 0));
  for (size_t k = 0; k < order.size(); ++k) {
    WGPUBuffer buffer = buffers[order[k]];
    auto t0 = Clock::now();
    wgpuBufferDestroy(buffer);
    wgpuBufferRelease(buffer);
    auto t1 = Clock::now();
    free_ns[k] = elapsed_ns(t0, t1);
    if (k % kPollEvery == kPollEvery - 1) ctx.poll(false);
  }
  ctx.wait_idle();
  ctx.check("destroying buffers");
  return {summarise(std::move(alloc_ns)), summarise(std::move(free_ns))};
}

struct SubResult {
  uint32_t page_mb = 0;
  OpTimes alloc, free;
  // Second round on the same suballocator: its pages survived the frees, as they do while a
  // streaming engine loads and evicts tiles; no page is created in this round.
  OpTimes warm_alloc, warm_free;
  uint32_t warm_new_pages = 0;
  gpu::SuballocatorStats after_alloc, after_free;
  bool coalesced = false;  // every page back to one free range after freeing everything
};

SubResult bench_suballocator(gpu::Context& ctx, const SuballocArgs& args, uint32_t page_mb,
                             const std::vector<uint64_t>& sizes,
                             const std::vector<uint32_t>& order) {
  SubResult r;
  r.page_mb = page_mb;
  std::vector<double> alloc_ns(sizes.size()), free_ns(sizes.size());
  {
    gpu::Suballocator sub(ctx, uint64_t(page_mb) << 20);
    std::vector<gpu::SubAllocation> allocations(sizes.size());
    for (size_t i = 0; i < sizes.size(); ++i) {
      auto t0 = Clock::now();
      allocations[i] = sub.allocate(sizes[i], kUsage);
      auto t1 = Clock::now();
      alloc_ns[i] = elapsed_ns(t0, t1);
      if (i % kPollEvery == kPollEvery - 1) ctx.poll(false);
    }
    ctx.poll(false);
    ctx.check("creating suballocator pages");
    r.after_alloc = sub.stats();
    if (args.touch) {
      std::vector<WGPUBuffer> buffers;
      std::vector<uint64_t> offsets;
      for (const auto& a : allocations) {
        buffers.push_back(a.buffer);
        offsets.push_back(a.offset);
      }
      touch(ctx, buffers, offsets);
    }
    for (size_t k = 0; k < order.size(); ++k) {
      const gpu::SubAllocation& a = allocations[order[k]];
      auto t0 = Clock::now();
      sub.free(a);
      auto t1 = Clock::now();
      free_ns[k] = elapsed_ns(t0, t1);
      if (k % kPollEvery == kPollEvery - 1) ctx.poll(false);
    }
    r.after_free = sub.stats();
    r.coalesced = r.after_free.bytes_used == 0;
    for (const auto& page : sub.pages(kUsage))
      r.coalesced = r.coalesced && page.free_ranges.size() == 1 && page.free_bytes == page.size;

    std::vector<double> warm_alloc_ns(sizes.size()), warm_free_ns(sizes.size());
    for (size_t i = 0; i < sizes.size(); ++i) {
      auto t0 = Clock::now();
      allocations[i] = sub.allocate(sizes[i], kUsage);
      auto t1 = Clock::now();
      warm_alloc_ns[i] = elapsed_ns(t0, t1);
      if (i % kPollEvery == kPollEvery - 1) ctx.poll(false);
    }
    r.warm_new_pages = sub.stats().pages - r.after_alloc.pages;
    for (size_t k = 0; k < order.size(); ++k) {
      const gpu::SubAllocation& a = allocations[order[k]];
      auto t0 = Clock::now();
      sub.free(a);
      auto t1 = Clock::now();
      warm_free_ns[k] = elapsed_ns(t0, t1);
      if (k % kPollEvery == kPollEvery - 1) ctx.poll(false);
    }
    r.warm_alloc = summarise(std::move(warm_alloc_ns));
    r.warm_free = summarise(std::move(warm_free_ns));
  }  // pages destroyed here, untimed
  ctx.wait_idle();
  ctx.check("destroying suballocator pages");
  r.alloc = summarise(std::move(alloc_ns));
  r.free = summarise(std::move(free_ns));
  return r;
}

void run_suballoc(const SuballocArgs& args) {
  if (args.min_kb > args.max_kb)
    fail("--min-kb ({}) must not exceed --max-kb ({})", args.min_kb, args.max_kb);
  if (args.page_mb.empty()) fail("--page-mb: give at least one page size");

  gpu::ContextOptions options;
  options.backend = args.backend;
  auto ctx = gpu::create_context(options);
  for (uint32_t mb : args.page_mb)
    if ((uint64_t(mb) << 20) > ctx->limits.maxBufferSize)
      fail("--page-mb {}: pages of {} bytes exceed the device's maxBufferSize ({})", mb,
           uint64_t(mb) << 20, ctx->limits.maxBufferSize);

  // The same sizes (multiples of 4 bytes, uniform in [min, max] KiB) and free order for every
  // configuration.
  std::mt19937_64 rng(args.seed);
  std::uniform_int_distribution<uint64_t> words(uint64_t(args.min_kb) * 256,
                                                uint64_t(args.max_kb) * 256);
  std::vector<uint64_t> sizes(args.count);
  for (uint64_t& s : sizes) s = words(rng) * 4;
  std::vector<uint32_t> order = free_order(args, rng);
  uint64_t total_bytes = std::accumulate(sizes.begin(), sizes.end(), uint64_t(0));

  const auto& d = ctx->description;
  std::printf(
      "stipple bench suballoc: %u vertex buffers (Vertex|CopyDst), %u-%u KiB, %.1f MiB in "
      "all, seed %u, free order %s%s\n",
      args.count, args.min_kb, args.max_kb, double(total_bytes) / (1 << 20), args.seed,
      args.free_order.c_str(), args.touch ? ", touched" : "");
  std::printf("backend %s (%s) on %s [%s]; driver: %s\n", d.backend.c_str(), d.graphics_api.c_str(),
              d.device.c_str(), d.adapter_type.c_str(), d.description.c_str());
  std::fflush(stdout);

  // Warm-up: first calls into the implementation load code and build caches.
  {
    std::vector<uint64_t> warm_sizes(std::min<size_t>(64, sizes.size()), 64 << 10);
    std::vector<uint32_t> warm_order(warm_sizes.size());
    std::iota(warm_order.begin(), warm_order.end(), 0u);
    bench_direct(*ctx, SuballocArgs{}, warm_sizes, warm_order);
  }
  double clock_ns = clock_overhead_ns();

  // Repetitions alternate the configurations so that machine noise hits all of them alike; the
  // tables show the median over repetitions of each per-run value.
  std::vector<DirectResult> direct_runs;
  std::vector<std::vector<SubResult>> sub_runs(args.page_mb.size());
  for (uint32_t rep = 0; rep < args.repeat; ++rep) {
    std::fprintf(stderr, "bench suballoc: run %u/%u: direct createBuffer...\n", rep + 1,
                 args.repeat);
    direct_runs.push_back(bench_direct(*ctx, args, sizes, order));
    for (size_t p = 0; p < args.page_mb.size(); ++p) {
      std::fprintf(stderr, "bench suballoc: run %u/%u: suballocator, %u MB pages...\n", rep + 1,
                   args.repeat, args.page_mb[p]);
      sub_runs[p].push_back(bench_suballocator(*ctx, args, args.page_mb[p], sizes, order));
    }
  }
  DirectResult direct;
  direct.alloc = median_of(direct_runs, [](const DirectResult& r) { return r.alloc; });
  direct.free = median_of(direct_runs, [](const DirectResult& r) { return r.free; });
  std::vector<SubResult> results;
  for (const auto& runs : sub_runs) {
    SubResult r = runs.front();  // page counts and stats are the same in every run
    r.alloc = median_of(runs, [](const SubResult& x) { return x.alloc; });
    r.free = median_of(runs, [](const SubResult& x) { return x.free; });
    r.warm_alloc = median_of(runs, [](const SubResult& x) { return x.warm_alloc; });
    r.warm_free = median_of(runs, [](const SubResult& x) { return x.warm_free; });
    for (const SubResult& x : runs) r.coalesced = r.coalesced && x.coalesced;
    results.push_back(r);
  }

  std::printf("\nDirect allocation (cf. Table 2)\n");
  std::printf("%12s %12s | %12s %12s\n", "Alloc (us)", "Free (ns)", "p50 alloc", "p50 free");
  std::printf("%12.2f %12.1f | %12.2f %12.1f\n", direct.alloc.mean / 1e3, direct.free.mean,
              direct.alloc.p50 / 1e3, direct.free.p50);
  std::printf("\nSuballocator (cf. Table 3)\n");
  std::printf("%10s %7s %12s %12s %14s %13s %10s | %12s %12s\n", "Page (MB)", "Pages", "Alloc (us)",
              "Free (ns)", "Alloc speedup", "Free speedup", "Used (%)", "p50 alloc", "p50 free");
  for (const SubResult& r : results) {
    double used = r.after_alloc.bytes_reserved
                      ? 100.0 * double(r.after_alloc.bytes_used) / r.after_alloc.bytes_reserved
                      : 0.0;
    std::printf("%10u %7u %12.2f %12.1f %13.1fx %12.1fx %10.1f | %12.2f %12.1f\n", r.page_mb,
                r.after_alloc.pages, r.alloc.mean / 1e3, r.free.mean,
                direct.alloc.mean / r.alloc.mean, direct.free.mean / r.free.mean, used,
                r.alloc.p50 / 1e3, r.free.p50);
  }
  std::printf("\nSuballocator, second round with the pages kept (streaming steady state)\n");
  std::printf("%10s %10s %12s %12s %14s %13s | %12s %12s\n", "Page (MB)", "New pages", "Alloc (us)",
              "Free (ns)", "Alloc speedup", "Free speedup", "p50 alloc", "p50 free");
  for (const SubResult& r : results)
    std::printf("%10u %10u %12.3f %12.1f %13.1fx %12.1fx | %12.3f %12.1f\n", r.page_mb,
                r.warm_new_pages, r.warm_alloc.mean / 1e3, r.warm_free.mean,
                direct.alloc.mean / r.warm_alloc.mean, direct.free.mean / r.warm_free.mean,
                r.warm_alloc.p50 / 1e3, r.warm_free.p50);
  std::printf(
      "\nMeans of per-operation steady_clock intervals (median over %u run%s); each "
      "includes ~%.0f ns of clock overhead.\n",
      args.repeat, args.repeat == 1 ? "" : "s", clock_ns);
  for (const SubResult& r : results)
    if (!r.coalesced)
      std::printf("warning: %u MB pages did not coalesce after freeing\n", r.page_mb);

  if (!args.json.empty()) {
    nlohmann::json j;
    j["benchmark"] = "suballoc";
    j["backend"] = d.backend;
    j["adapter"] = d.device;
    j["adapter_description"] = d.description;
    j["adapter_type"] = d.adapter_type;
    j["graphics_api"] = d.graphics_api;
    j["usage"] = "Vertex|CopyDst";
    j["count"] = args.count;
    j["min_kb"] = args.min_kb;
    j["max_kb"] = args.max_kb;
    j["seed"] = args.seed;
    j["free_order"] = args.free_order;
    j["touch"] = args.touch;
    j["total_bytes"] = total_bytes;
    j["clock_overhead_ns"] = clock_ns;
    j["repeat"] = args.repeat;
    nlohmann::json direct_alloc_runs, direct_free_runs;
    for (const DirectResult& r : direct_runs) {
      direct_alloc_runs.push_back(r.alloc.mean / 1e3);
      direct_free_runs.push_back(r.free.mean);
    }
    j["direct"] = {{"alloc_us", direct.alloc.mean / 1e3}, {"free_ns", direct.free.mean},
                   {"alloc", to_json(direct.alloc)},      {"free", to_json(direct.free)},
                   {"alloc_us_runs", direct_alloc_runs},  {"free_ns_runs", direct_free_runs}};
    nlohmann::json rows = nlohmann::json::array();
    for (size_t p = 0; p < results.size(); ++p) {
      const SubResult& r = results[p];
      const auto& s = r.after_alloc;
      nlohmann::json alloc_runs, free_runs;
      for (const SubResult& x : sub_runs[p]) {
        alloc_runs.push_back(x.alloc.mean / 1e3);
        free_runs.push_back(x.free.mean);
      }
      rows.push_back({{"page_mb", r.page_mb},
                      {"pages", s.pages},
                      {"dedicated_buffers", s.dedicated_buffers},
                      {"alloc_us", r.alloc.mean / 1e3},
                      {"free_ns", r.free.mean},
                      {"alloc_speedup", direct.alloc.mean / r.alloc.mean},
                      {"free_speedup", direct.free.mean / r.free.mean},
                      {"alloc", to_json(r.alloc)},
                      {"free", to_json(r.free)},
                      {"bytes_reserved", s.bytes_reserved},
                      {"bytes_used", s.bytes_used},
                      {"fragmentation", s.fragmentation},
                      {"page_searches", s.page_searches},
                      {"bytes_used_after_free", r.after_free.bytes_used},
                      {"coalesced_after_free", r.coalesced},
                      {"alloc_us_runs", alloc_runs},
                      {"free_ns_runs", free_runs},
                      {"warm",
                       {{"alloc_us", r.warm_alloc.mean / 1e3},
                        {"free_ns", r.warm_free.mean},
                        {"alloc_speedup", direct.alloc.mean / r.warm_alloc.mean},
                        {"free_speedup", direct.free.mean / r.warm_free.mean},
                        {"new_pages", r.warm_new_pages},
                        {"alloc", to_json(r.warm_alloc)},
                        {"free", to_json(r.warm_free)}}}});
    }
    j["suballocator"] = rows;
    write_file_atomically(args.json, j.dump(2) + "\n");
  }
}

}  // namespace

void add_bench_command(CLI::App& cli) {
  auto* bench = cli.add_subcommand("bench", "Micro-benchmarks (the seed paper's measurements)");
  bench->require_subcommand(1);

  auto args = std::make_shared<SuballocArgs>();
  auto* cmd = bench->add_subcommand(
      "suballoc", "Buffer suballocator vs direct createBuffer (seed 000, Tables 2-3)");
  cmd->add_option("--count", args->count, "Number of allocations")
      ->check(CLI::Range(1u, 1'000'000u))
      ->capture_default_str();
  cmd->add_option("--min-kb", args->min_kb, "Smallest buffer in KiB")
      ->check(CLI::Range(1u, 1u << 20))
      ->capture_default_str();
  cmd->add_option("--max-kb", args->max_kb, "Largest buffer in KiB")
      ->check(CLI::Range(1u, 1u << 20))
      ->capture_default_str();
  cmd->add_option("--page-mb", args->page_mb, "Page sizes in MiB, comma-separated")
      ->delimiter(',')
      ->check(CLI::Range(1u, 4096u))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "WebGPU implementation: dawn or wgpu "
                  "(default: $STIPPLE_BACKEND, else wgpu)")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->add_option("--seed", args->seed, "Random seed for sizes (and free order)")
      ->capture_default_str();
  cmd->add_option("--free-order", args->free_order, "Free in allocation order, reverse or random")
      ->check(CLI::IsMember({"alloc", "reverse", "random"}))
      ->capture_default_str();
  cmd->add_option("--repeat", args->repeat,
                  "Run the whole protocol this many times; tables show medians over runs")
      ->check(CLI::Range(1u, 1000u))
      ->capture_default_str();
  cmd->add_flag("--touch", args->touch,
                "Write into every buffer after allocating (untimed): forces lazily "
                "initialised memory into use");
  cmd->callback([args] { run_suballoc(*args); });
  add_bench_raster_command(*bench);
  add_bench_virtual_command(*bench);
  add_bench_stream_command(*bench);
  add_bench_batches_command(*bench);
  add_bench_bandwidth_command(*bench);
  add_bench_splats_command(*bench);
  add_bench_points_command(bench);
}

}  // namespace stipple::app
