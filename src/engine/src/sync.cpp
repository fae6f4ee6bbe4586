#include "stipple/engine/sync.hpp"

namespace stipple {

void install_render_sync(Registry& main) {
  main.insert_resource(RenderSyncQueue{});
  main.on_construct<SyncTo<RenderWorldTag>>([](Registry& r, Entity e, SyncTo<RenderWorldTag>&) {
    r.resource<RenderSyncQueue>().to_create.push_back(e);
  });
  // Unlinking goes through RenderEntity, so removing either component or the entity ends the twin.
  main.on_destroy<SyncTo<RenderWorldTag>>(
      [](Registry& r, Entity e, SyncTo<RenderWorldTag>&) { r.remove<RenderEntity>(e); });
  main.on_destroy<RenderEntity>([](Registry& r, Entity, RenderEntity& link) {
    r.resource<RenderSyncQueue>().to_destroy.push_back(link.entity);
  });
}

void apply_render_sync(Registry& main, Registry& render) {
  auto& queue = main.resource<RenderSyncQueue>();
  for (Entity twin : queue.to_destroy) render.destroy(twin);
  queue.to_destroy.clear();
  // Swap out first: emplacing RenderEntity below must not touch the list being walked.
  std::vector<Entity> create;
  create.swap(queue.to_create);
  for (Entity e : create) {
    if (!main.has<SyncTo<RenderWorldTag>>(e) || main.has<RenderEntity>(e)) continue;
    Entity twin = render.create();
    render.emplace<MainEntity>(twin, e);
    main.emplace<RenderEntity>(e, twin);
  }
}

}  // namespace stipple
