#pragma once
// The node hierarchy of an untrusted glTF document, shared by the point (glb_points.cpp) and
// splat (splat_gltf.cpp) readers: which nodes carry a mesh, and each one's world matrix. Every
// index is checked, and a cyclic or too deep hierarchy is an error naming the file rather than
// an endless walk. Private to the io module.
#include <cstddef>
#include <string_view>
#include <vector>

#include <glm/mat4x4.hpp>
#include <nlohmann/json.hpp>

namespace stipple::io::gltf_nodes {

// A node's local matrix: `matrix`, else translation * rotation * scale (glTF's order).
glm::dmat4 node_matrix(const nlohmann::json& node, std::string_view name);

struct MeshNode {
  size_t node = 0;
  size_t mesh = 0;  // checked against the document's meshes
  glm::dmat4 world{1.0};
};

// The nodes with a mesh under the document's scene (`scene`, else the first; with no scenes,
// every node that is nobody's child), depth-first from the last root, with their world
// matrices.
std::vector<MeshNode> mesh_nodes(const nlohmann::json& document, std::string_view name);

}  // namespace stipple::io::gltf_nodes
