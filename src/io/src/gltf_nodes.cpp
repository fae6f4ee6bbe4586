#include "gltf_nodes.hpp"

#include <cstdint>

#include <glm/gtc/quaternion.hpp>

#include "stipple/core/error.hpp"

namespace stipple::io::gltf_nodes {

using json = nlohmann::json;

namespace {

// `j` as an index below `size`, or fail naming what it is.
size_t checked_index(const json& j, size_t size, std::string_view name, std::string_view what) {
  if (!j.is_number_integer() || j.get<int64_t>() < 0 || j.get<uint64_t>() >= size)
    fail("{}: {} index out of range", name, what);
  return j.get<size_t>();
}

}  // namespace

glm::dmat4 node_matrix(const json& node, std::string_view name) {
  auto numbers = [&](const char* key, size_t n) {
    const json& a = node[key];
    if (!a.is_array() || a.size() != n) fail("{}: node {} does not hold {} numbers", name, key, n);
    std::vector<double> v;
    for (const auto& x : a) {
      if (!x.is_number()) fail("{}: node {} holds a non-number", name, key);
      v.push_back(x.get<double>());
    }
    return v;
  };
  glm::dmat4 m(1.0);
  if (node.contains("matrix")) {
    auto v = numbers("matrix", 16);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m[c][r] = v[size_t(c * 4 + r)];
    return m;
  }
  if (node.contains("translation")) {
    auto t = numbers("translation", 3);
    m[3] = glm::dvec4(t[0], t[1], t[2], 1.0);
  }
  if (node.contains("rotation")) {
    auto q = numbers("rotation", 4);  // glTF order x, y, z, w
    m = m * glm::dmat4(glm::mat4_cast(glm::normalize(glm::dquat(q[3], q[0], q[1], q[2]))));
  }
  if (node.contains("scale")) {
    auto s = numbers("scale", 3);
    m[0] *= s[0];
    m[1] *= s[1];
    m[2] *= s[2];
  }
  return m;
}

std::vector<MeshNode> mesh_nodes(const json& j, std::string_view name) {
  const json nodes = j.value("nodes", json::array());
  const json meshes = j.value("meshes", json::array());
  if (!nodes.is_array() || !meshes.is_array()) fail("{}: nodes or meshes is not an array", name);
  std::vector<size_t> roots;
  const json scenes = j.value("scenes", json::array());
  if (scenes.is_array() && !scenes.empty()) {
    const size_t s =
        j.contains("scene") ? checked_index(j["scene"], scenes.size(), name, "scene") : 0;
    if (!scenes[s].is_object()) fail("{}: scene {} is not an object", name, s);
    const json roots_json = scenes[s].value("nodes", json::array());
    if (!roots_json.is_array()) fail("{}: scene {} nodes is not an array", name, s);
    for (const auto& n : roots_json)
      roots.push_back(checked_index(n, nodes.size(), name, "scene node"));
  } else {
    std::vector<bool> is_child(nodes.size());
    for (const auto& n : nodes)
      if (n.is_object())
        for (const auto& ch : n.value("children", json::array()))
          if (ch.is_number_integer() && ch.get<int64_t>() >= 0 && ch.get<uint64_t>() < nodes.size())
            is_child[ch.get<size_t>()] = true;
    for (size_t i = 0; i < nodes.size(); ++i)
      if (!is_child[i]) roots.push_back(i);
  }

  struct Item {
    size_t node;
    glm::dmat4 parent;
    int depth;
  };
  std::vector<Item> stack;
  for (size_t r : roots) stack.push_back({r, glm::dmat4(1.0), 0});
  std::vector<MeshNode> out;
  size_t visits = 0;
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    // A node graph with cycles (invalid glTF) must not loop forever.
    if (item.depth > 64 || ++visits > nodes.size() * 4 + 16)
      fail("{}: node hierarchy is cyclic or too deep", name);
    const json& node = nodes[item.node];
    if (!node.is_object()) fail("{}: node {} is not an object", name, item.node);
    const glm::dmat4 m = item.parent * node_matrix(node, name);
    const json children = node.value("children", json::array());
    if (!children.is_array()) fail("{}: node {} children is not an array", name, item.node);
    for (const auto& ch : children)
      stack.push_back({checked_index(ch, nodes.size(), name, "child node"), m, item.depth + 1});
    if (node.contains("mesh"))
      out.push_back({item.node, checked_index(node["mesh"], meshes.size(), name, "node mesh"), m});
  }
  return out;
}

}  // namespace stipple::io::gltf_nodes
