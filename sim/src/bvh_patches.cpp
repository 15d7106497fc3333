// Surface patches for the two-level BVH (see bvh_patches.h).

#include "bvh_patches.h"

#include <algorithm>
#include <utility>

#include <glm/common.hpp>

#include "morton.h"

namespace bisturi::sim {

namespace {

constexpr std::uint32_t kUnassigned = 0xffffffffu;

}  // namespace

std::uint32_t SurfacePatches::code_of(const SurfaceTriangles& triangles, std::size_t triangle,
                                      const std::vector<glm::dvec3>& x) const {
  const std::uint32_t* t = &triangles.indices[3 * triangle];
  const glm::dvec3 c = (x[t[0]] + x[t[1]] + x[t[2]]) / 3.0;
  const glm::dvec3 u = (c - lo_) * scale_;
  return morton_code(u);
}

void SurfacePatches::assign(const SurfaceTriangles& triangles, const std::vector<glm::dvec3>& x) {
  patch_of_face_.clear();
  first_code_.clear();
  if (triangles.size() == 0) return;
  glm::dvec3 lo = x[triangles.indices[0]], hi = lo;
  for (const std::uint32_t v : triangles.indices) {
    lo = glm::min(lo, x[v]);
    hi = glm::max(hi, x[v]);
  }
  lo_ = lo;
  const glm::dvec3 size = glm::max(hi - lo, glm::dvec3(1e-12));
  scale_ = glm::dvec3(1024.0) / size;

  // One entry per face (its first triangle gives the centroid), with its triangle count. A
  // face's triangles are consecutive (triangulate_surface fans each face in turn).
  struct FaceEntry {
    std::uint32_t code, face, triangles;
  };
  std::vector<FaceEntry> faces;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const std::uint32_t f = triangles.face_of[t].idx;
    if (t > 0 && triangles.face_of[t - 1].idx == f) {
      ++faces.back().triangles;
      continue;
    }
    faces.push_back({code_of(triangles, t, x), f, 1});
  }
  std::sort(faces.begin(), faces.end(), [](const FaceEntry& a, const FaceEntry& b) {
    return std::pair(a.code, a.face) < std::pair(b.code, b.face);
  });
  std::size_t in_patch = kTrianglesPerPatch;  // the first face opens a patch
  for (const FaceEntry& e : faces) {
    if (in_patch >= kTrianglesPerPatch) {
      first_code_.push_back(e.code);
      in_patch = 0;
    }
    if (e.face >= patch_of_face_.size()) patch_of_face_.resize(e.face + 1, kUnassigned);
    patch_of_face_[e.face] = static_cast<std::uint32_t>(first_code_.size() - 1);
    in_patch += e.triangles;
  }
}

void SurfacePatches::assign_new_faces(const SurfaceTriangles& triangles,
                                      const std::vector<glm::dvec3>& x) {
  if (first_code_.empty()) {
    assign(triangles, x);
    return;
  }
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const std::uint32_t f = triangles.face_of[t].idx;
    if (f < patch_of_face_.size() && patch_of_face_[f] != kUnassigned) continue;
    if (f >= patch_of_face_.size()) patch_of_face_.resize(f + 1, kUnassigned);
    const std::uint32_t code = code_of(triangles, t, x);
    const auto after = std::upper_bound(first_code_.begin(), first_code_.end(), code);
    patch_of_face_[f] = after == first_code_.begin()
                            ? 0u
                            : static_cast<std::uint32_t>(after - first_code_.begin() - 1);
  }
}

std::vector<std::vector<std::uint32_t>> SurfacePatches::split(
    const SurfaceTriangles& triangles) const {
  std::vector<std::vector<std::uint32_t>> out(count());
  for (std::size_t t = 0; t < triangles.size(); ++t)
    out[patch_of_face_[triangles.face_of[t].idx]].push_back(static_cast<std::uint32_t>(t));
  return out;
}

std::vector<std::uint32_t> match_primitives(const std::vector<std::uint32_t>& prim_corners,
                                            const std::vector<std::uint32_t>& home,
                                            const std::vector<std::uint32_t>& indices,
                                            std::vector<std::uint32_t>& prim_triangle) {
  // Open addressing over home's positions, keyed by the corner triple (a power of two at least
  // twice the entries: short probe runs). kDeadTriangle marks an empty or consumed slot.
  std::size_t size = 16;
  while (size < 2 * home.size())
    size *= 2;
  const std::size_t mask = size - 1;
  auto slot_of = [&](const std::uint32_t* t) {
    std::uint64_t h = t[0] * 0x9e3779b97f4a7c15ull;
    h ^= (h >> 29) + t[1] * 0xbf58476d1ce4e5b9ull;
    h ^= (h >> 31) + t[2] * 0x94d049bb133111ebull;
    return static_cast<std::size_t>(h ^ (h >> 32)) & mask;
  };
  std::vector<std::uint32_t> table(size, kDeadTriangle);
  for (std::size_t k = 0; k < home.size(); ++k) {
    std::size_t s = slot_of(&indices[3 * std::size_t{home[k]}]);
    while (table[s] != kDeadTriangle)
      s = (s + 1) & mask;
    table[s] = static_cast<std::uint32_t>(k);
  }
  std::vector<std::uint8_t> matched(home.size(), 0);
  const std::size_t np = prim_corners.size() / 3;
  prim_triangle.assign(np, kDeadTriangle);
  for (std::size_t i = 0; i < np; ++i) {
    const std::uint32_t* c = &prim_corners[3 * i];
    // Probe to the first empty slot: consumed entries stay in the table (a triple can repeat).
    for (std::size_t s = slot_of(c); table[s] != kDeadTriangle; s = (s + 1) & mask) {
      const std::uint32_t k = table[s];
      const std::uint32_t* t = &indices[3 * std::size_t{home[k]}];
      if (matched[k] || t[0] != c[0] || t[1] != c[1] || t[2] != c[2]) continue;
      matched[k] = 1;
      prim_triangle[i] = home[k];
      break;
    }
  }
  std::vector<std::uint32_t> unmatched;
  for (std::size_t k = 0; k < home.size(); ++k)
    if (!matched[k]) unmatched.push_back(home[k]);
  return unmatched;
}

}  // namespace bisturi::sim
