#pragma once
// Host-visible buffers that stay mapped between uses, for streaming data to the GPU every frame
// without an intermediate copy (seed 002, III-C: the mapped buffers that carry new points and
// the compaction info). The CPU writes straight into a slot's mapped range; the slot is
// unmapped when a copy out of it is recorded, and mapped again (asynchronously) once that
// copy's submission has been made, ready for a later frame. Two slots let one frame's copy run
// on the GPU while the next frame is written.
//
// Readback is the same in reverse: a MapRead buffer kept for reuse, so reading a result back
// every frame allocates nothing.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple {
class ThreadPool;
}

namespace stipple::gpu {

// Maps `buffer` asynchronously; its callback leaves the outcome in `state` (any struct with a
// `phase` whose Phase has Mapping, Mapped and Failed, and a `message`), set to Mapping here. The
// callback holds a reference of its own, so the state outlives its owner: a map still pending
// when the buffer goes away is answered later, cancelled.
template <typename State>
void map_async(WGPUBuffer buffer, WGPUMapMode mode, uint64_t size,
               const std::shared_ptr<State>& state) {
  WGPUBufferMapCallbackInfo cb = WGPU_BUFFER_MAP_CALLBACK_INFO_INIT;
  cb.mode = WGPUCallbackMode_AllowProcessEvents;
  cb.userdata1 = new std::shared_ptr<State>(state);
  cb.callback = [](WGPUMapAsyncStatus status, WGPUStringView message, void* userdata, void*) {
    std::unique_ptr<std::shared_ptr<State>> kept(static_cast<std::shared_ptr<State>*>(userdata));
    if (status == WGPUMapAsyncStatus_Success) {
      (*kept)->phase = State::Phase::Mapped;
    } else {
      (*kept)->phase = State::Phase::Failed;
      (*kept)->message = to_string(message);
    }
  };
  state->phase = State::Phase::Mapping;
  wgpuBufferMapAsync(buffer, mode, 0, size, cb);
}

// For readbacks taken a frame or more later: with `wait`, waits until `mapping()` says no map is
// pending (or the device is lost); else one poll that does not wait (natively: the browser
// answers maps from its event loop). Fails if the device was lost, naming `what`.
void settle_maps(Context& ctx, bool wait, const std::function<bool()>& mapping,
                 std::string_view what);

struct StagingSlotState;  // map state, shared with the map callback

struct StagingRing {
  struct Slot {
    Buffer buffer;
    std::shared_ptr<StagingSlotState> state;
  };
  std::vector<Slot> slots;
  uint64_t slot_bytes = 0;
  uint32_t next = 0;
};

StagingRing create_staging_ring(Context& ctx, uint64_t slot_bytes, uint32_t slots = 2,
                                std::string_view label = "staging");

// The next slot, mapped for writing (waits for its map to complete when a previous use is still
// in flight). `data` is valid until end_staging_write.
struct StagingWrite {
  uint8_t* data = nullptr;
  WGPUBuffer buffer = nullptr;
  uint64_t size = 0;
  uint32_t slot = 0;
};
StagingWrite begin_staging_write(Context& ctx, StagingRing& ring);
// Whether begin_staging_write would take its slot without waiting (it is mapped, or its map
// failed, which begin_staging_write reports); asks for the slot's map when it is due and not yet
// asked for. Events are processed elsewhere (a poll).
bool staging_write_ready(StagingRing& ring);
// Unmaps the slot: copies out of it may be recorded now. Call staging_submitted once the
// command buffer holding them has been submitted; the slot is then mapped again for reuse.
void end_staging_write(StagingRing& ring, const StagingWrite& write);
void staging_submitted(StagingRing& ring);

// Large uploads: host ranges copied into device buffers through a ring of mapped slots, the
// copy into a slot running on `pool` (every core) while the GPU copies the previous slot out.
// A queue write would stage everything once more, on one thread; a buffer born mapped pins its
// whole size first (3 GB/s for 2 GB on an H200 host).
struct BufferUpload {
  WGPUBuffer buffer = nullptr;
  uint64_t offset = 0;  // multiples of 4, as are the sizes
  const void* data = nullptr;
  uint64_t size = 0;
};
void upload_through_staging(Context& ctx, std::span<const BufferUpload> uploads, ThreadPool* pool,
                            uint64_t slot_bytes = uint64_t(64) << 20, uint32_t slots = 4);

// Host bytes the ring holds mapped.
inline uint64_t staging_bytes(const StagingRing& ring) {
  return ring.slot_bytes * ring.slots.size();
}

// A reusable MapRead buffer; read_back copies `size` bytes at `offset` of `source` through it
// (blocking) into `out`.
struct ReadbackBuffer {
  Buffer buffer;
  uint64_t capacity = 0;
};
void read_back(Context& ctx, ReadbackBuffer& readback, WGPUBuffer source, uint64_t offset,
               uint64_t size, void* out);

// Results read back without waiting: a copy into a free slot is recorded with a frame's
// commands; once that frame is submitted the slot is mapped asynchronously, and a later frame
// takes the newest result that has arrived. `tag` says what a result belongs to (a frame
// number, a camera's index).
struct ReadbackRing {
  struct Slot {
    Buffer buffer;
    std::shared_ptr<StagingSlotState> state;
    uint64_t tag = 0, size = 0;
  };
  std::vector<Slot> slots;
  uint64_t slot_bytes = 0;
};
ReadbackRing create_readback_ring(Context& ctx, uint64_t slot_bytes, uint32_t slots = 3);
// Records a copy of `size` bytes of `source` into a free slot; false when every slot is busy.
bool record_readback(ReadbackRing& ring, WGPUCommandEncoder encoder, WGPUBuffer source,
                     uint64_t size, uint64_t tag);
// After the commands holding recorded copies were submitted: their maps are requested.
void readback_submitted(ReadbackRing& ring);
// Processes events without blocking (or, with `wait`, until some result arrives while any is
// in flight); copies the newest arrived result into `out`, frees every arrived slot, and
// returns its tag; nullopt when none arrived.
std::optional<uint64_t> take_readback(Context& ctx, ReadbackRing& ring, void* out, bool wait);
// Whether any copy is recorded or in flight; whether a slot is free for a copy.
bool readback_busy(const ReadbackRing& ring);
bool readback_free(const ReadbackRing& ring);

}  // namespace stipple::gpu
