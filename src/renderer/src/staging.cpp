#include "stipple/renderer/staging.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include "stipple/core/error.hpp"
#include "stipple/core/thread_pool.hpp"

namespace stipple::gpu {

// Written by the map callback (under the context's event processing), read by the waits.
struct StagingSlotState {
  enum class Phase { Mapped, Unmapped, Submitted, Mapping, Failed };
  Phase phase = Phase::Mapped;
  std::string message;
};

namespace {

using Phase = StagingSlotState::Phase;

struct MapWait {
  bool done = false;
  WGPUMapAsyncStatus status = WGPUMapAsyncStatus_Error;
  std::string message;
};

void request_map(StagingRing::Slot& slot, uint64_t size) {
  map_async(slot.buffer.get(), WGPUMapMode_Write, size, slot.state);
}

}  // namespace

void settle_maps(Context& ctx, bool wait, const std::function<bool()>& mapping,
                 std::string_view what) {
  if (wait) {
    ctx.wait_until([&] { return !mapping() || ctx.lost; });
  } else {
#ifndef __EMSCRIPTEN__
    ctx.poll(false);
#endif
  }
  if (ctx.lost) fail("WebGPU device lost while reading {} back", what);
}

StagingRing create_staging_ring(Context& ctx, uint64_t slot_bytes, uint32_t slots,
                                std::string_view label) {
  StagingRing ring;
  ring.slot_bytes = (slot_bytes + 3) & ~uint64_t(3);
  if (ring.slot_bytes > ctx.limits.maxBufferSize)
    fail("staging buffer of {} bytes exceeds the device's maxBufferSize ({})", ring.slot_bytes,
         ctx.limits.maxBufferSize);
  for (uint32_t i = 0; i < slots; ++i) {
    WGPUBufferDescriptor desc = WGPU_BUFFER_DESCRIPTOR_INIT;
    desc.label = to_view(label);
    desc.size = ring.slot_bytes;
    desc.usage = WGPUBufferUsage_MapWrite | WGPUBufferUsage_CopySrc;
    desc.mappedAtCreation = true;  // born mapped: the first use needs no round trip
    StagingRing::Slot slot;
    slot.buffer = Buffer(wgpuDeviceCreateBuffer(ctx.device.get(), &desc));
    if (!slot.buffer) fail("could not create staging buffer ({} bytes)", ring.slot_bytes);
    slot.state = std::make_shared<StagingSlotState>();
    // Touched now, so that the host memory it takes is resident (and measured) from the start.
    if (void* data = wgpuBufferGetMappedRange(slot.buffer.get(), 0, ring.slot_bytes))
      std::memset(data, 0, ring.slot_bytes);
    ring.slots.push_back(std::move(slot));
  }
  return ring;
}

StagingWrite begin_staging_write(Context& ctx, StagingRing& ring) {
  if (ring.slots.empty()) fail("staging ring has no slots");
  const uint32_t index = ring.next;
  ring.next = (ring.next + 1) % uint32_t(ring.slots.size());
  StagingRing::Slot& slot = ring.slots[index];
  if (slot.state->phase == Phase::Submitted) request_map(slot, ring.slot_bytes);
  if (slot.state->phase == Phase::Unmapped)
    fail("staging slot {} was unmapped but never submitted", index);
  ctx.wait_until([&] { return slot.state->phase != Phase::Mapping || ctx.lost; });
  ctx.check("mapping a staging buffer");
  if (slot.state->phase != Phase::Mapped)
    fail("mapping a staging buffer failed: {}", slot.state->message);
  void* data = wgpuBufferGetMappedRange(slot.buffer.get(), 0, ring.slot_bytes);
  if (!data) fail("staging buffer's mapped range is null");
  return {static_cast<uint8_t*>(data), slot.buffer.get(), ring.slot_bytes, index};
}

bool staging_write_ready(StagingRing& ring) {
  if (ring.slots.empty()) return false;
  StagingRing::Slot& slot = ring.slots[ring.next];
  if (slot.state->phase == Phase::Submitted) request_map(slot, ring.slot_bytes);
  // A failed map is "ready" too: begin_staging_write then reports it.
  return slot.state->phase == Phase::Mapped || slot.state->phase == Phase::Failed;
}

void end_staging_write(StagingRing& ring, const StagingWrite& write) {
  StagingRing::Slot& slot = ring.slots.at(write.slot);
  wgpuBufferUnmap(slot.buffer.get());
  slot.state->phase = Phase::Unmapped;
}

void staging_submitted(StagingRing& ring) {
  // Map requests go out now so that they complete while the GPU works; nothing waits here.
  for (auto& slot : ring.slots)
    if (slot.state->phase == Phase::Unmapped) {
      slot.state->phase = Phase::Submitted;
      request_map(slot, ring.slot_bytes);
    }
}

void upload_through_staging(Context& ctx, std::span<const BufferUpload> uploads, ThreadPool* pool,
                            uint64_t slot_bytes, uint32_t slots) {
  uint64_t total = 0;
  for (const BufferUpload& u : uploads) total += u.size;
  if (total == 0) return;
  slot_bytes = std::min<uint64_t>(std::max<uint64_t>(slot_bytes & ~uint64_t(3), 4),
                                  (total + 3) & ~uint64_t(3));
  StagingRing ring = create_staging_ring(ctx, slot_bytes, slots, "upload-staging");
  for (const BufferUpload& u : uploads) {
    for (uint64_t at = 0; at < u.size; at += slot_bytes) {
      const uint64_t n = std::min(slot_bytes, u.size - at);
      StagingWrite w = begin_staging_write(ctx, ring);
      const auto* src = static_cast<const uint8_t*>(u.data) + at;
      constexpr uint64_t kPiece = uint64_t(1) << 22;
      const size_t pieces = size_t((n + kPiece - 1) / kPiece);
      auto copy = [&](size_t b, size_t e) {
        for (size_t k = b; k < e; ++k) {
          const uint64_t o = k * kPiece;
          std::memcpy(w.data + o, src + o, std::min(kPiece, n - o));
        }
      };
      if (pool && pieces > 1)
        pool->parallel_for(pieces, 1, copy);
      else
        copy(0, pieces);
      end_staging_write(ring, w);
      WGPUCommandEncoderDescriptor desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
      CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &desc));
      wgpuCommandEncoderCopyBufferToBuffer(encoder.get(), w.buffer, 0, u.buffer, u.offset + at,
                                           (n + 3) & ~uint64_t(3));
      CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), nullptr));
      WGPUCommandBuffer raw = commands.get();
      wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
      staging_submitted(ring);
    }
  }
  ctx.wait_idle();  // the ring's buffers go with this scope
}

void read_back(Context& ctx, ReadbackBuffer& readback, WGPUBuffer source, uint64_t offset,
               uint64_t size, void* out) {
  const uint64_t padded = (size + 3) & ~uint64_t(3);
  if (padded == 0) return;
  if (readback.capacity < padded) {
    readback.buffer =
        create_buffer(ctx, padded, WGPUBufferUsage_MapRead | WGPUBufferUsage_CopyDst, "readback");
    readback.capacity = padded;
  }
  WGPUCommandEncoderDescriptor enc_desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &enc_desc));
  wgpuCommandEncoderCopyBufferToBuffer(encoder.get(), source, offset, readback.buffer.get(), 0,
                                       padded);
  CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), nullptr));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  MapWait map;
  WGPUBufferMapCallbackInfo cb = WGPU_BUFFER_MAP_CALLBACK_INFO_INIT;
  cb.mode = WGPUCallbackMode_AllowProcessEvents;
  cb.callback = [](WGPUMapAsyncStatus status, WGPUStringView message, void* userdata, void*) {
    auto* r = static_cast<MapWait*>(userdata);
    r->done = true;
    r->status = status;
    r->message = to_string(message);
  };
  cb.userdata1 = &map;
  wgpuBufferMapAsync(readback.buffer.get(), WGPUMapMode_Read, 0, padded, cb);
  ctx.wait_until([&] { return map.done || ctx.lost; });
  ctx.check("reading a buffer back");
  if (map.status != WGPUMapAsyncStatus_Success) fail("buffer readback failed: {}", map.message);
  const void* mapped = wgpuBufferGetConstMappedRange(readback.buffer.get(), 0, padded);
  if (!mapped) fail("buffer readback failed: mapped range is null");
  std::memcpy(out, mapped, size);
  wgpuBufferUnmap(readback.buffer.get());
}

ReadbackRing create_readback_ring(Context& ctx, uint64_t slot_bytes, uint32_t slots) {
  ReadbackRing ring;
  ring.slot_bytes = std::max<uint64_t>(4, (slot_bytes + 3) & ~uint64_t(3));
  for (uint32_t i = 0; i < slots; ++i) {
    ReadbackRing::Slot slot;
    slot.buffer = create_buffer(ctx, ring.slot_bytes,
                                WGPUBufferUsage_MapRead | WGPUBufferUsage_CopyDst, "readback-ring");
    slot.state = std::make_shared<StagingSlotState>();
    slot.state->phase = Phase::Unmapped;  // here: free (not mapped, nothing recorded)
    ring.slots.push_back(std::move(slot));
  }
  return ring;
}

// Readback slots: Unmapped = free, Submitted = copy recorded, Mapping = map requested,
// Mapped = result arrived.
bool record_readback(ReadbackRing& ring, WGPUCommandEncoder encoder, WGPUBuffer source,
                     uint64_t size, uint64_t tag) {
  const uint64_t padded = (size + 3) & ~uint64_t(3);
  if (padded > ring.slot_bytes)
    fail("readback of {} bytes into slots of {}", size, ring.slot_bytes);
  for (auto& slot : ring.slots) {
    if (slot.state->phase != Phase::Unmapped) continue;
    if (padded > 0)
      wgpuCommandEncoderCopyBufferToBuffer(encoder, source, 0, slot.buffer.get(), 0, padded);
    slot.state->phase = Phase::Submitted;
    slot.tag = tag;
    slot.size = size;
    return true;
  }
  return false;
}

void readback_submitted(ReadbackRing& ring) {
  for (auto& slot : ring.slots)
    if (slot.state->phase == Phase::Submitted)
      map_async(slot.buffer.get(), WGPUMapMode_Read, ring.slot_bytes, slot.state);
}

bool readback_busy(const ReadbackRing& ring) {
  for (const auto& slot : ring.slots)
    if (slot.state->phase != Phase::Unmapped) return true;
  return false;
}

bool readback_free(const ReadbackRing& ring) {
  for (const auto& slot : ring.slots)
    if (slot.state->phase == Phase::Unmapped) return true;
  return false;
}

std::optional<uint64_t> take_readback(Context& ctx, ReadbackRing& ring, void* out, bool wait) {
  auto arrived = [&ring] {
    for (const auto& slot : ring.slots)
      if (slot.state->phase == Phase::Mapped || slot.state->phase == Phase::Failed) return true;
    return false;
  };
  auto mapping = [&ring] {
    for (const auto& slot : ring.slots)
      if (slot.state->phase == Phase::Mapping) return true;
    return false;
  };
  ctx.poll(false);
  if (wait) ctx.wait_until([&] { return arrived() || !mapping() || ctx.lost; });
  ctx.check("reading back");
  ReadbackRing::Slot* newest = nullptr;
  for (auto& slot : ring.slots) {
    if (slot.state->phase == Phase::Failed) fail("readback failed: {}", slot.state->message);
    if (slot.state->phase == Phase::Mapped && (!newest || slot.tag > newest->tag)) newest = &slot;
  }
  if (!newest) return std::nullopt;
  const uint64_t tag = newest->tag;
  if (newest->size > 0) {
    const void* mapped = wgpuBufferGetConstMappedRange(newest->buffer.get(), 0, ring.slot_bytes);
    if (!mapped) fail("readback: mapped range is null");
    std::memcpy(out, mapped, newest->size);
  }
  for (auto& slot : ring.slots)
    if (slot.state->phase == Phase::Mapped) {
      wgpuBufferUnmap(slot.buffer.get());
      slot.state->phase = Phase::Unmapped;
    }
  return tag;
}

}  // namespace stipple::gpu
