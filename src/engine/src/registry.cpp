#include "stipple/engine/registry.hpp"

#include <exception>

#include <fmt/format.h>

namespace stipple {

Entity Registry::create() {
  ++alive_count_;
  if (!free_.empty()) {
    uint32_t index = free_.back();
    free_.pop_back();
    slots_[index].alive = true;
    return {index, slots_[index].version};
  }
  if (slots_.size() >= UINT32_MAX) fail("registry is out of entity slots");
  slots_.push_back({0, true, false});
  return {uint32_t(slots_.size() - 1), 0};
}

bool Registry::destroy(Entity e) {
  if (!alive(e) || slots_[e.index].dying) return false;
  slots_[e.index].dying = true;
  // By index: hooks may create pools (growing pools_); they cannot add components to e.
  // A throwing hook does not leave the entity half-destroyed: the rest still runs, then the first
  // exception propagates.
  std::exception_ptr error;
  for (size_t i = 0; i < pools_.size(); ++i) {
    try {
      if (pools_[i]) pools_[i]->remove(*this, e);
    } catch (...) {
      if (!error) error = std::current_exception();
    }
  }
  Slot& slot = slots_[e.index];
  slot.alive = false;
  slot.dying = false;
  --alive_count_;
  // A slot whose version would wrap is retired, so no old handle can ever match it again.
  if (++slot.version != UINT32_MAX) free_.push_back(e.index);
  if (error) std::rethrow_exception(error);
  return true;
}

void Registry::check_writable(Entity e, std::string_view what) const {
  if (!alive(e)) fail("cannot add {} to entity {}: it is not alive", what, describe(e));
  if (slots_[e.index].dying)
    fail("cannot add {} to entity {}: it is being destroyed", what, describe(e));
}

std::string Registry::describe(Entity e) {
  if (!e) return "null";
  return fmt::format("{}v{}", e.index, e.version);
}

}  // namespace stipple
