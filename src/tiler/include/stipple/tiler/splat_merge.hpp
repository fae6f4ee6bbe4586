#pragma once
// Level of detail for Gaussian splats: the splats of a tile's children reduced to fewer,
// larger splats that keep their mass, centre, spread and colour (moment matching).
//
// A group of splats i (mean mu_i, covariance Sigma_i = R_i S_i^2 R_i^T, opacity a_i) becomes one
// splat with weight w_i = a_i * A_i, where A_i = s1 s2 + s2 s3 + s3 s1 is proportional to the
// splat's mean projected area: W = sum w_i, mean mu = sum w_i mu_i / W, covariance
// Sigma = sum w_i (Sigma_i + (mu_i - mu)(mu_i - mu)^T) / W, brought back to scales and a rotation
// by a symmetric 3x3 eigen-decomposition (Jacobi); opacity W / A (clamped to 1, A of the merged
// splat: the covered area is kept), SH coefficients (DC and higher) weighted by w_i. A group of
// one splat is copied unchanged.
//
// Groups come from an adaptive octree over the node's cube: cells are split, most populous
// first, while the number of cells stays within a target, so dense regions keep finer cells.
#include <cstdint>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/splats.hpp"

namespace stipple::tiler {

// Eigenvalues (ascending) and unit eigenvectors (columns of `vectors`, a proper rotation) of a
// symmetric 3x3 matrix.
void symmetric_eigen(const glm::dmat3& m, glm::dvec3& values, glm::dmat3& vectors);

// The moment-matched merge of `members` of `in`.
void merge_group(const io::SplatSet& in, const uint32_t* members, size_t count, io::SplatSet& out,
                 size_t out_index);

struct MergeResult {
  io::SplatSet splats;
  // The count-weighted root mean square edge of the cells that merged more than one splat (0
  // when none did): the detail the merge removed, the tile's geometric error.
  double cell_size = 0;
};

// At most max(1, target) splats for `in`, whose positions lie in the cube at `cube_min` with
// edge `cube_size`. Fewer splats than the target are returned as they are.
MergeResult merge_splats(const io::SplatSet& in, const glm::dvec3& cube_min, double cube_size,
                         size_t target);

// The splats reordered along a Morton curve over their bounds (10 bits an axis): neighbours in
// the arrays are neighbours in space, so that gzip (SPZ) finds the repeated high bytes of
// nearby positions and similar colours and scales.
io::SplatSet morton_sorted(const io::SplatSet& in);

}  // namespace stipple::tiler
