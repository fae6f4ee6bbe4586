#pragma once
// Entity handles and compile-time type identity for the ECS (see registry.hpp).
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string_view>

namespace stipple {

// An entity is a 32-bit slot index plus the slot's version at creation. Destroying an entity
// bumps its slot's version, so handles kept past destruction are detected as stale even after
// the slot is recycled.
struct Entity {
  uint32_t index = UINT32_MAX;
  uint32_t version = 0;

  friend bool operator==(Entity, Entity) = default;
  explicit operator bool() const { return index != UINT32_MAX; }
};

inline constexpr Entity kNullEntity{};

// A dense id per C++ type, shared by all registries; used to index pool and resource tables.
namespace detail {
inline std::atomic<uint32_t> next_type_id{0};
}
template <typename T>
uint32_t type_id() {
  static const uint32_t id = detail::next_type_id.fetch_add(1, std::memory_order_relaxed);
  return id;
}

// The readable name of T for error messages ("stipple::Transform"), from the compiler's
// function signature, so no RTTI demangling is needed.
template <typename T>
constexpr std::string_view type_name() {
  std::string_view p = __PRETTY_FUNCTION__;
  const std::string_view key = "T = ";
  size_t start = p.find(key);
  if (start == std::string_view::npos) return p;
  start += key.size();
  size_t end = p.find_first_of(";]", start);
  return p.substr(start, end - start);
}

}  // namespace stipple

template <>
struct std::hash<stipple::Entity> {
  size_t operator()(stipple::Entity e) const noexcept {
    return std::hash<uint64_t>{}((uint64_t(e.version) << 32) | e.index);
  }
};
