#pragma once
// A small sparse-set ECS with EnTT's shape: entities, one pool per component type, views,
// resources (singletons by type) and construct/destroy hooks. EnTT itself is in none of the
// package registries we can reach, so this is our own (docs/architecture.md).
//
// Rules worth knowing:
// - References returned by emplace/get/try_get stay valid until a component of the same type is
//   added to or removed from any entity (pools are contiguous vectors).
// - Destroy hooks run after the component has left its pool and receive the removed value, so a
//   hook may freely modify the registry, including removing the counterpart of a relation whose
//   own hook then finds nothing left to undo (that is what makes relations reentrancy-safe).
// - Views iterate the smallest pool backwards: removing components from, or destroying, the
//   entity being visited is safe; entities added during iteration are not visited; removing or
//   destroying *other* entities is memory-safe but may skip or repeat visits.
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/engine/entity.hpp"

namespace stipple {

class Registry;

// The type-erased half of a pool: a sparse set mapping entity index -> dense position.
class SparseSet {
 public:
  static constexpr uint32_t kPageSize = 4096;
  static constexpr uint32_t kAbsent = UINT32_MAX;

  virtual ~SparseSet() = default;
  bool contains(Entity e) const {
    uint32_t d = dense_index(e.index);
    return d != kAbsent && dense_[d] == e;  // full compare: stale versions are not found
  }
  size_t size() const { return dense_.size(); }
  bool empty() const { return dense_.empty(); }
  const std::vector<Entity>& entities() const { return dense_; }
  // Removes e's component and runs the destroy hooks; false when e has none.
  virtual bool remove(Registry& registry, Entity e) = 0;

 protected:
  uint32_t dense_index(uint32_t index) const {
    size_t page = index / kPageSize;
    if (page >= sparse_.size() || !sparse_[page]) return kAbsent;
    return sparse_[page][index % kPageSize];
  }
  uint32_t& sparse_slot(uint32_t index) {
    size_t page = index / kPageSize;
    if (page >= sparse_.size()) sparse_.resize(page + 1);
    if (!sparse_[page]) {
      sparse_[page] = std::make_unique<uint32_t[]>(kPageSize);
      std::fill_n(sparse_[page].get(), kPageSize, kAbsent);
    }
    return sparse_[page][index % kPageSize];
  }
  void push_entity(Entity e) {
    sparse_slot(e.index) = uint32_t(dense_.size());
    dense_.push_back(e);
  }
  // Swap-and-pop of the dense entity array at position i.
  void pop_entity(uint32_t i) {
    Entity gone = dense_[i];
    if (i + 1 != dense_.size()) {
      dense_[i] = dense_.back();
      sparse_slot(dense_[i].index) = i;
    }
    dense_.pop_back();
    sparse_slot(gone.index) = kAbsent;
  }

  std::vector<std::unique_ptr<uint32_t[]>> sparse_;  // pages of dense positions
  std::vector<Entity> dense_;
};

template <typename T>
class Pool final : public SparseSet {
 public:
  // Construct hooks get the stored component; destroy hooks get the value just removed.
  using Hook = std::function<void(Registry&, Entity, T&)>;

  T& get(Entity e) { return data_[dense_index(e.index)]; }  // precondition: contains(e)
  const T& get(Entity e) const { return data_[dense_index(e.index)]; }
  T* try_get(Entity e) { return contains(e) ? &data_[dense_index(e.index)] : nullptr; }

  template <typename... Args>
  T& insert(Entity e, Args&&... args) {
    if constexpr (std::is_aggregate_v<T>)
      data_.push_back(T{std::forward<Args>(args)...});
    else
      data_.emplace_back(std::forward<Args>(args)...);
    push_entity(e);
    return data_.back();
  }

  bool remove(Registry& registry, Entity e) override {
    if (!contains(e)) return false;
    uint32_t i = dense_index(e.index);
    T value = std::move(data_[i]);
    if (i + 1 != data_.size()) data_[i] = std::move(data_.back());
    data_.pop_back();
    pop_entity(i);
    // deque: hooks registered meanwhile do not move the ones being called.
    for (size_t h = 0; h < on_destroy.size(); ++h) on_destroy[h](registry, e, value);
    return true;
  }

  std::deque<Hook> on_construct;
  std::deque<Hook> on_destroy;

 private:
  std::vector<T> data_;
};

template <typename... T>
class View;

class Registry {
 public:
  Registry() = default;
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;
  Registry(Registry&&) = default;
  Registry& operator=(Registry&&) = default;

  Entity create();
  // Runs the destroy hooks of all the entity's components, then frees the slot with a new
  // version. False for stale handles and for an entity already being destroyed.
  bool destroy(Entity e);
  bool alive(Entity e) const {
    return e.index < slots_.size() && slots_[e.index].alive && slots_[e.index].version == e.version;
  }
  // Alive, but inside destroy(): its destroy hooks are running and nothing may be added to it.
  bool being_destroyed(Entity e) const { return alive(e) && slots_[e.index].dying; }
  size_t size() const { return alive_count_; }  // live entities

  template <typename T, typename... Args>
  T& emplace(Entity e, Args&&... args) {
    check_writable(e, type_name<T>());
    Pool<T>& p = pool<T>();
    if (p.contains(e)) fail("entity {} already has a {}", describe(e), type_name<T>());
    p.insert(e, std::forward<Args>(args)...);
    for (size_t h = 0; h < p.on_construct.size() && p.contains(e); ++h)
      p.on_construct[h](*this, e, p.get(e));
    if (!p.contains(e)) fail("a construct hook removed the {} it was given", type_name<T>());
    return p.get(e);
  }
  // Replacement is remove + emplace, so hooks (relations) see the old value go and the new come.
  template <typename T>
  T& emplace_or_replace(Entity e, T value) {
    remove<T>(e);
    return emplace<T>(e, std::move(value));
  }
  // Assigns in place when e has a T (no hooks run: not for relations), else emplaces. For
  // per-frame extraction into the render world.
  template <typename T>
  T& insert_or_assign(Entity e, T value) {
    if (T* existing = try_get<T>(e)) return *existing = std::move(value);
    return emplace<T>(e, std::move(value));
  }
  template <typename T>
  T& get(Entity e) {
    Pool<T>* p = find_pool<T>();
    if (!p || !p->contains(e)) fail("entity {} has no {}", describe(e), type_name<T>());
    return p->get(e);
  }
  template <typename T>
  const T& get(Entity e) const {
    return const_cast<Registry*>(this)->get<T>(e);
  }
  template <typename T>
  T* try_get(Entity e) {
    Pool<T>* p = find_pool<T>();
    return p ? p->try_get(e) : nullptr;
  }
  template <typename T>
  const T* try_get(Entity e) const {
    return const_cast<Registry*>(this)->try_get<T>(e);
  }
  // True when e has all of T...
  template <typename... T>
  bool has(Entity e) const {
    return ((find_pool<T>() && find_pool<T>()->contains(e)) && ...);
  }
  // Removes T from e (running destroy hooks); false when e had none. Stale handles are a no-op.
  template <typename T>
  bool remove(Entity e) {
    Pool<T>* p = find_pool<T>();
    return p && p->remove(*this, e);
  }
  template <typename... T>
  View<T...> view() {
    return View<T...>(&pool<T>()...);
  }
  template <typename T>
  size_t count() const {
    Pool<T>* p = find_pool<T>();
    return p ? p->size() : 0;
  }

  template <typename T>
  void on_construct(typename Pool<T>::Hook hook) {
    pool<T>().on_construct.push_back(std::move(hook));
  }
  template <typename T>
  void on_destroy(typename Pool<T>::Hook hook) {
    pool<T>().on_destroy.push_back(std::move(hook));
  }

  // Resources: one value per type, owned by the registry. insert replaces an existing one.
  template <typename T>
  T& insert_resource(T value) {
    auto owned = std::make_shared<T>(std::move(value));
    T& ref = *owned;
    resource_slot(type_id<T>()) = std::move(owned);
    return ref;
  }
  template <typename T>
  T& resource() {
    if (T* r = try_resource<T>()) return *r;
    fail("missing resource {} (is the plugin that provides it added?)", type_name<T>());
  }
  template <typename T>
  T* try_resource() {
    uint32_t id = type_id<T>();
    return id < resources_.size() ? static_cast<T*>(resources_[id].get()) : nullptr;
  }
  template <typename T>
  bool has_resource() {
    return try_resource<T>() != nullptr;
  }
  template <typename T>
  bool remove_resource() {
    uint32_t id = type_id<T>();
    if (id >= resources_.size() || !resources_[id]) return false;
    resources_[id].reset();
    return true;
  }

  template <typename T>
  Pool<T>& pool() {
    // view<const T> would otherwise silently get a pool of its own.
    static_assert(std::is_same_v<T, std::remove_cvref_t<T>>, "component types are plain types");
    uint32_t id = type_id<T>();
    if (id >= pools_.size()) pools_.resize(id + 1);
    if (!pools_[id]) pools_[id] = std::make_unique<Pool<T>>();
    return static_cast<Pool<T>&>(*pools_[id]);
  }
  template <typename T>
  Pool<T>* find_pool() const {
    uint32_t id = type_id<T>();
    return id < pools_.size() ? static_cast<Pool<T>*>(pools_[id].get()) : nullptr;
  }

  static std::string describe(Entity e);

 private:
  struct Slot {
    uint32_t version = 0;
    bool alive = false;
    bool dying = false;  // inside destroy(): its hooks may not add components to it
  };
  void check_writable(Entity e, std::string_view what) const;
  std::shared_ptr<void>& resource_slot(uint32_t id) {
    if (id >= resources_.size()) resources_.resize(id + 1);
    return resources_[id];
  }

  std::vector<Slot> slots_;
  std::vector<uint32_t> free_;
  size_t alive_count_ = 0;
  std::vector<std::unique_ptr<SparseSet>> pools_;  // by type_id<T>()
  std::vector<std::shared_ptr<void>> resources_;   // by type_id<T>()
};

// Entities having all of T...: iterates the smallest pool (backwards) and checks the others.
template <typename... T>
class View {
 public:
  explicit View(Pool<T>*... pools) : pools_{pools...} {
    lead_ = nullptr;
    ((lead_ = (!lead_ || pools->size() < lead_->size()) ? static_cast<SparseSet*>(pools) : lead_),
     ...);
  }

  // fn(Entity, T&...) or fn(T&...).
  template <typename Fn>
  void each(Fn&& fn) {
    for (size_t i = lead_->size(); i-- > 0;) {
      if (i >= lead_->size()) continue;  // the visit before removed several entries
      Entity e = lead_->entities()[i];
      if (!contains(e)) continue;
      if constexpr (std::is_invocable_v<Fn, Entity, T&...>)
        fn(e, std::get<Pool<T>*>(pools_)->get(e)...);
      else
        fn(std::get<Pool<T>*>(pools_)->get(e)...);
    }
  }
  bool contains(Entity e) const { return (std::get<Pool<T>*>(pools_)->contains(e) && ...); }
  // An upper bound of the number of entities visited.
  size_t size_hint() const { return lead_->size(); }

  // Range-for over entities, with the same iteration rules as each().
  class Iterator {
   public:
    Iterator(const View* view, size_t pos) : view_(view), pos_(pos) { settle(); }
    Entity operator*() const { return view_->lead_->entities()[pos_ - 1]; }
    Iterator& operator++() {
      --pos_;
      settle();
      return *this;
    }
    bool operator==(const Iterator& o) const { return pos_ == o.pos_; }

   private:
    void settle() {
      while (pos_ > 0 &&
             (pos_ > view_->lead_->size() || !view_->contains(view_->lead_->entities()[pos_ - 1])))
        --pos_;
    }
    const View* view_;
    size_t pos_;  // one past the dense position visited
  };
  Iterator begin() const { return Iterator(this, lead_->size()); }
  Iterator end() const { return Iterator(this, 0); }

 private:
  std::tuple<Pool<T>*...> pools_;
  SparseSet* lead_;
};

}  // namespace stipple
