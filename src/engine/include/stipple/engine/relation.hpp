#pragma once
// Relations (seed 000, section 3.2): a directed link between two entities of one registry.
// Relation<Tag> on the source names the target; a hook keeps InverseRelation<Tag> on the target
// listing every source. Removing either side's component, or destroying either entity, removes
// the counterpart. Each Tag (ChildOf, RendersTo, ...) gives distinct component types, so an
// entity can take part in many kinds of relation at once.
#include <algorithm>
#include <vector>

#include "stipple/engine/registry.hpp"

namespace stipple {

template <typename Tag>
struct Relation {
  Entity target;
};

template <typename Tag>
struct InverseRelation {
  std::vector<Entity> sources;  // in the order the relations were made
};

// Relation kinds used by the built-in plugins.
struct ChildOfTag {};
using ChildOf = Relation<ChildOfTag>;
using Children = InverseRelation<ChildOfTag>;

namespace detail {
template <typename Tag>
struct RelationHooksInstalled {};
}  // namespace detail

// Installs the hooks that keep Relation<Tag> and InverseRelation<Tag> consistent in `registry`;
// calling it again is a no-op. Making a relation to a dead entity throws stipple::Error.
template <typename Tag>
void register_relation(Registry& registry) {
  if (registry.has_resource<detail::RelationHooksInstalled<Tag>>()) return;
  registry.insert_resource(detail::RelationHooksInstalled<Tag>{});

  registry.on_construct<Relation<Tag>>([](Registry& r, Entity source, Relation<Tag>& rel) {
    Entity target = rel.target;
    if (!r.alive(target) || r.being_destroyed(target)) {
      r.remove<Relation<Tag>>(source);
      fail("relation {} from entity {} to entity {}: the target is not alive", type_name<Tag>(),
           Registry::describe(source), Registry::describe(target));
    }
    if (auto* inverse = r.try_get<InverseRelation<Tag>>(target))
      inverse->sources.push_back(source);
    else
      r.emplace<InverseRelation<Tag>>(target, std::vector<Entity>{source});
  });

  // The source's relation went: forget the source, and drop the inverse once nobody points at
  // the target. When the inverse itself is being removed it is no longer found here.
  registry.on_destroy<Relation<Tag>>([](Registry& r, Entity source, Relation<Tag>& rel) {
    auto* inverse = r.try_get<InverseRelation<Tag>>(rel.target);
    if (!inverse) return;
    std::erase(inverse->sources, source);
    if (inverse->sources.empty()) r.remove<InverseRelation<Tag>>(rel.target);
  });

  // The target's inverse went (target destroyed, or the component removed): every source loses
  // its relation. Each Relation hook then finds no inverse and returns.
  registry.on_destroy<InverseRelation<Tag>>(
      [](Registry& r, Entity target, InverseRelation<Tag>& inverse) {
        for (Entity source : inverse.sources) {
          const auto* rel = r.try_get<Relation<Tag>>(source);
          if (rel && rel->target == target) r.remove<Relation<Tag>>(source);
        }
      });
}

}  // namespace stipple
