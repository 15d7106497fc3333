#include "bisturi/sim/soft_body.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"
#include "bisturi/sim/units.h"
#include "vertex_corners.h"
#include "volume_kernels.h"

namespace bisturi::sim {
namespace {

std::atomic<std::uint64_t> g_generation{0};
std::atomic<std::uint64_t> g_lineage{0};

double signed_volume(const SurfaceTriangles& t, const std::vector<glm::dvec3>& x) {
  return six_volume(t.indices.data(), 0, t.size(), x.data()) / 6.0;
}

}  // namespace

SoftBody::SoftBody(Dlfl mesh, const Material& material)
    : mesh_(std::move(mesh)), material_(material), lineage_(++g_lineage) {
  check_material(material_);
  if (mesh_.num_faces() == 0) throw SimInputError("soft body: the solid has no faces");
  auto& props = mesh_.vertex_properties();
  x_ = &props.add<glm::dvec3>("sim.position_m");
  v_ = &props.add<glm::dvec3>("sim.velocity_m_s");
  rest_ = &props.add<glm::dvec3>("sim.rest_position_m");
  anchored_ = &props.add<std::uint8_t>("sim.anchored", 0);
  for (std::uint32_t i = 0; i < mesh_.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (!mesh_.alive(v)) continue;
    (*x_)[v] = scene_to_sim(mesh_.position(v));
    (*rest_)[v] = (*x_)[v];
  }
  // Room for the elements of a few cuts: growing an array in a cut would copy all of it, and
  // fault in fresh pages, while the session waits (about 2 ms of a 5 cm cut at 20k vertices).
  // Reserved pages that are never written cost no memory.
  auto room = [](std::size_t n) { return n + n / 4 + 64; };
  const std::size_t nv = room(mesh_.vertex_capacity());
  mesh_.reserve(nv, room(mesh_.corner_capacity()), room(mesh_.face_capacity()),
                room(mesh_.edge_capacity()));
  mass_.reserve(nv);
  kinematic_.reserve(nv);
  target_.reserve(nv);
  force_.reserve(nv);
  warm_.reserve(nv);
  topology_version_ = mesh_.topology_version() + 1;  // force the first build
  refresh_topology();
  const double v0 = signed_volume(triangles_, rest_->raw());
  orientation_ = v0 < 0.0 ? -1.0 : 1.0;
  rest_volume_m3_ = closed_ ? std::abs(v0) : 0.0;
}

SoftBody::SoftBody(const SoftBody& other)
    : mesh_(other.mesh_),
      material_(other.material_),
      mass_(other.mass_),
      kinematic_(other.kinematic_),
      kinematic_count_(other.kinematic_count_),
      constraint_edits_(other.constraint_edits_),
      loaded_(other.loaded_),
      target_(other.target_),
      force_(other.force_),
      warm_(other.warm_),
      contacts_(other.contacts_),
      springs_(other.springs_),
      triangles_(other.triangles_),
      closed_(other.closed_),
      rest_volume_m3_(other.rest_volume_m3_),
      orientation_(other.orientation_),
      topology_version_(other.topology_version_),
      derived_generation_(++g_generation),
      lineage_(++g_lineage),
      state_edits_(other.state_edits_),
      frozen_(other.frozen_) {
  // The state arrays live in the copied mesh's properties.
  auto& props = mesh_.vertex_properties();
  x_ = &props.get<glm::dvec3>("sim.position_m");
  v_ = &props.get<glm::dvec3>("sim.velocity_m_s");
  rest_ = &props.get<glm::dvec3>("sim.rest_position_m");
  anchored_ = &props.get<std::uint8_t>("sim.anchored");
  // spring_change_ stays empty: with a fresh lineage nothing derived from the original's
  // springs is reused for the copy.
}

void SoftBody::set_loads_from(const SoftBody& other) {
  clear_forces();
  for (const std::uint32_t i : other.loaded_)
    force_[i] = other.force_[i];  // the sum of its calls; assigning twice is harmless
  loaded_ = other.loaded_;
  contacts_ = other.contacts_;
}

void SoftBody::resize_arrays() {
  const std::size_t n = mesh_.vertex_capacity();
  mass_.assign(n, 0.0);
  kinematic_.resize(n, 0);
  target_.resize(n, glm::dvec3(0.0));
  force_.resize(n, glm::dvec3(0.0));
  warm_.resize(n, glm::dvec3(0.0));
}

void SoftBody::ensure_capacity() {
  ++state_edits_;  // new vertex slots
  const std::size_t n = mesh_.vertex_capacity();
  mass_.resize(n, 0.0);
  kinematic_.resize(n, 0);
  target_.resize(n, glm::dvec3(0.0));
  force_.resize(n, glm::dvec3(0.0));
  warm_.resize(n, glm::dvec3(0.0));
}

void SoftBody::rebuild_masses() {
  // Each real face's area (vector area of the polygon at rest) is shared equally by its corners.
  const double area_density = material_.density_kg_per_m3 * material_.thickness_m;
  const auto& rest = rest_->raw();
  std::vector<std::uint32_t> ring;
  for (std::uint32_t fi = 0; fi < mesh_.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh_.alive(f) || mesh_.is_bounding(f)) continue;
    const CornerId first = mesh_.first_corner(f);
    if (mesh_.is_point_sphere(first)) continue;
    ring.clear();
    CornerId c = first;
    do {
      ring.push_back(mesh_.vertex(c).idx);
      c = mesh_.next(c);
    } while (c != first);
    glm::dvec3 twice_area(0.0);
    for (std::size_t i = 0; i < ring.size(); ++i) {
      twice_area += glm::cross(rest[ring[i]], rest[ring[(i + 1) % ring.size()]]);
    }
    const double share = 0.5 * glm::length(twice_area) * area_density / double(ring.size());
    for (std::uint32_t v : ring)
      mass_[v] += share;
  }
}

bool SoftBody::refresh_topology() {
  if (mesh_.topology_version() == topology_version_) return false;
  resize_arrays();
  springs_ = build_springs(mesh_, rest_->raw(), material_);
  spring_change_.from_generation = 0;
  spring_change_.vertices.clear();
  rebuild_masses();
  finish_refresh(true);
  return true;
}

void SoftBody::finish_refresh(bool surface) {
  if (surface) {
    triangles_ = triangulate_surface(mesh_);
    closed_ = material_.bulk_modulus_Pa > 0.0 && !any_bounding_face();
  }
  topology_version_ = mesh_.topology_version();
  derived_generation_ = ++g_generation;
}

bool SoftBody::refresh_topology_local(std::span<const VertexId> touched) {
  if (mesh_.topology_version() == topology_version_) return false;
  ensure_capacity();
  const std::size_t n = mesh_.vertex_capacity();
  // The region: every vertex of a face around a touched vertex. Springs and masses outside it
  // do not depend on any face the edit changed (docs/sim/integrator.md, "Cuts").
  std::vector<std::uint8_t> region(n, 0);
  std::vector<std::uint32_t> verts;
  for (VertexId t : touched) {
    if (!mesh_.alive(t)) continue;
    for_each_corner(mesh_, t, [&](CornerId c) {
      const CornerId first = mesh_.first_corner(mesh_.face(c));
      CornerId k = first;
      do {
        const std::uint32_t v = mesh_.vertex(k).idx;
        if (!region[v]) {
          region[v] = 1;
          verts.push_back(v);
        }
        k = mesh_.next(k);
      } while (k != first);
    });
  }
  std::sort(verts.begin(), verts.end());
  // Every face the edit changed is around a region vertex.
  const std::vector<FaceId> faces = faces_around(mesh_, verts);
  // Springs: those with no end in the region are kept; the others come from the new faces.
  std::vector<Spring> near = build_springs_near(mesh_, rest_->raw(), material_, region, faces);
  // In place (no new multi-megabyte array: fresh pages cost more than the merge): drop the
  // region's springs, then merge the new ones in from the back.
  auto less = [](const Spring& x, const Spring& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; };
  // The vertices whose springs may change: the region and the other ends of its springs.
  std::vector<std::uint32_t>& changed = spring_change_.vertices;
  changed = verts;
  auto note = [&](const Spring& s) {
    if (!region[s.a]) changed.push_back(s.a);
    if (!region[s.b]) changed.push_back(s.b);
  };
  for (const Spring& s : near)
    note(s);
  std::erase_if(springs_, [&](const Spring& s) {
    const bool in_region = region[s.a] || region[s.b];
    if (in_region) note(s);
    return in_region;
  });
  std::sort(changed.begin(), changed.end());
  changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
  spring_change_.from_generation = derived_generation_;
  std::size_t i = springs_.size(), j = near.size();
  springs_.resize(i + j);
  for (std::size_t out = i + j; j > 0;) {
    if (i > 0 && less(near[j - 1], springs_[i - 1])) {
      springs_[--out] = springs_[--i];
    } else {
      springs_[--out] = near[--j];
    }
  }
  // Masses: each region vertex sums its corners' shares again (faces outside the region kept
  // their area and corner count, so the other vertices keep their masses).
  const double area_density = material_.density_kg_per_m3 * material_.thickness_m;
  const auto& rest = rest_->raw();
  for (std::uint32_t v : verts) {
    double m = 0.0;
    for_each_corner(mesh_, VertexId(v), [&](CornerId c) {
      const FaceId f = mesh_.face(c);
      if (mesh_.is_bounding(f) || mesh_.is_point_sphere(c)) return;
      glm::dvec3 twice_area(0.0);
      std::size_t count = 0;
      const CornerId first = mesh_.first_corner(f);
      CornerId k = first;
      do {
        twice_area += glm::cross(rest[mesh_.vertex(k).idx], rest[mesh_.vertex(mesh_.next(k)).idx]);
        ++count;
        k = mesh_.next(k);
      } while (k != first);
      m += 0.5 * glm::length(twice_area) * area_density / double(count);
    });
    mass_[v] = m;
  }
  // Triangles: the faces around the region again, the others' copied (into the storage of the
  // triangulation before last: fresh pages cost more than the copy).
  triangulate_changed_faces(mesh_, triangles_, faces, spare_triangles_);
  std::swap(triangles_, spare_triangles_);
  // A closed body stays closed unless a changed face is labelled (the others kept their labels);
  // an open one is checked in full.
  if (closed_) {
    for (const FaceId f : faces)
      if (mesh_.alive(f) && mesh_.is_bounding(f)) closed_ = false;
  } else {
    closed_ = material_.bulk_modulus_Pa > 0.0 && !any_bounding_face();
  }
  finish_refresh(false);
  return true;
}

bool SoftBody::any_bounding_face() const {
  for (std::uint32_t f = 0; f < mesh_.face_capacity(); ++f) {
    if (mesh_.alive(FaceId(f)) && mesh_.is_bounding(FaceId(f))) return true;
  }
  return false;
}

void SoftBody::set_anchored(VertexId v, bool anchored) {
  (*anchored_)[v] = anchored ? 1 : 0;
  if (anchored) (*v_)[v] = glm::dvec3(0.0);
  ++constraint_edits_;
}

void SoftBody::set_kinematic_target(VertexId v, const glm::dvec3& target_m) {
  if (!kinematic_[v.idx]) {
    kinematic_[v.idx] = 1;
    ++kinematic_count_;
    ++constraint_edits_;
  }
  target_[v.idx] = target_m;
}

void SoftBody::release_kinematic(VertexId v) {
  if (!kinematic_[v.idx]) return;
  kinematic_[v.idx] = 0;
  --kinematic_count_;
  ++constraint_edits_;
}

void SoftBody::add_contact(VertexId v, const glm::dvec3& normal, double depth_m,
                           double stiffness_N_per_m, std::int32_t probe) {
  force_[v.idx] += (stiffness_N_per_m * depth_m) * normal;
  contacts_.push_back({v.idx, normal, stiffness_N_per_m, probe});
  loaded_.push_back(v.idx);
}

void SoftBody::clear_forces() {
  // Only add_force and add_contact write forces, and they list the vertex.
  for (const std::uint32_t i : loaded_)
    force_[i] = glm::dvec3(0.0);
  loaded_.clear();
  contacts_.clear();
}

double SoftBody::volume_m3() const {
  return orientation_ * signed_volume(triangles_, x_->raw());
}

double SoftBody::kinetic_energy() const {
  double e = 0.0;
  const auto& v = v_->raw();
  for (std::size_t i = 0; i < mass_.size(); ++i)
    e += 0.5 * mass_[i] * glm::dot(v[i], v[i]);
  return e;
}

double SoftBody::elastic_energy() const {
  const auto& x = x_->raw();
  double e = 0.0;
  for (const Spring& s : springs_) {
    const double stretch = glm::length(x[s.b] - x[s.a]) - s.rest_m;
    e += 0.5 * s.k_N_per_m * stretch * stretch;
  }
  if (closed_ && rest_volume_m3_ > 0.0) {
    const double dv = volume_m3() - rest_volume_m3_;
    e += 0.5 * material_.bulk_modulus_Pa * dv * dv / rest_volume_m3_;
  }
  return e;
}

double SoftBody::total_energy(const glm::dvec3& gravity) const {
  double potential = 0.0;
  const auto& x = x_->raw();
  for (std::size_t i = 0; i < mass_.size(); ++i)
    potential -= mass_[i] * glm::dot(gravity, x[i]);
  return kinetic_energy() + elastic_energy() + potential;
}

void SoftBody::freeze() {
  frozen_ = true;
  std::fill(v_->raw().begin(), v_->raw().end(), glm::dvec3(0.0));
  std::fill(warm_.begin(), warm_.end(), glm::dvec3(0.0));
  clear_forces();
}

void SoftBody::write_positions_to_scene() {
  for (std::uint32_t i = 0; i < mesh_.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (mesh_.alive(v)) mesh_.set_position(v, sim_to_scene((*x_)[v]));
  }
}

std::uint64_t SoftBody::state_hash() const {
  std::uint64_t h = 1469598103934665603ull;
  auto mix = [&h](const std::vector<glm::dvec3>& data) {
    const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
    for (std::size_t i = 0; i < data.size() * sizeof(glm::dvec3); ++i) {
      h ^= bytes[i];
      h *= 1099511628211ull;
    }
  };
  mix(x_->raw());
  mix(v_->raw());
  return h;
}

}  // namespace bisturi::sim
