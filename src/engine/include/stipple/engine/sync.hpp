#pragma once
// Linking main-world entities to render-world twins (seed 000, section 3.2).
//
// Add SyncTo<RenderWorldTag> to a main-world entity and the engine creates a twin in the render
// world: the main entity gets RenderEntity{twin}, the twin gets MainEntity{main}. Removing
// SyncTo (or RenderEntity), or destroying the main entity, destroys the twin.
//
// When: hooks on the main registry only queue the work (the render thread may be using the
// render registry while the main world changes); the engine applies the queue at the start of
// the Extract sync point, with the render world idle, before any Extract system runs. So a twin
// exists from the first Extract after SyncTo was added, and is gone from the first Extract
// after its main entity went. Never destroy twins from the render side.
#include <vector>

#include "stipple/engine/registry.hpp"
#include "stipple/engine/world.hpp"

namespace stipple {

template <typename WorldTag>
struct SyncTo {};

struct RenderEntity {
  Entity entity;  // the twin in the render world
};
struct MainEntity {
  Entity entity;  // the source in the main world
};

// Main-registry resource: twins to create and destroy at the next sync point.
struct RenderSyncQueue {
  std::vector<Entity> to_create;   // main entities that got SyncTo
  std::vector<Entity> to_destroy;  // render twins whose link went
};

// Installs the hooks on the main registry (the engine does this itself).
void install_render_sync(Registry& main);
// Applies the queue: creates and links twins, destroys orphaned ones.
void apply_render_sync(Registry& main, Registry& render);

}  // namespace stipple
