#pragma once
// Vectors whose resize() leaves new elements default-initialised (for plain types: not written)
// instead of zeroing them. Arrays of hundreds of millions of words that are about to be
// overwritten would otherwise be zeroed by one thread, taking every page fault on that thread;
// with this allocator the first write, done in parallel by whoever fills the array, faults the
// pages in.
#include <memory>
#include <utility>
#include <vector>

namespace stipple {

template <typename T, typename Base = std::allocator<T>>
struct DefaultInitAllocator : Base {
  using Base::Base;
  template <typename U>
  struct rebind {
    using other =
        DefaultInitAllocator<U, typename std::allocator_traits<Base>::template rebind_alloc<U>>;
  };
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    std::allocator_traits<Base>::construct(static_cast<Base&>(*this), p,
                                           std::forward<Args>(args)...);
  }
};

template <typename T>
using UninitVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace stipple
