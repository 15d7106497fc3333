// Subdivision levels with OpenSubdiv: Far::TopologyRefiner refines the topology once, and
// Far::PrimvarRefinerReal<double> interpolates positions level by level on every update().

#include "bisturi/scene/lod/subdivision.h"

#include <opensubdiv/far/error.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefiner.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <string>
#include <utility>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"

namespace bisturi::lod {

namespace {

namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;
using Vec3 = Dlfl::Vec3;

// OpenSubdiv reports errors through a global callback that prints by default; the library must
// not print, so the message is kept for the exception instead.
thread_local std::string osd_message;
void keep_error(Far::ErrorType /*type*/, const char* message) {
  osd_message = message != nullptr ? message : "";
}
void ignore_warning(const char* /*message*/) {}

// Adaptors for PrimvarRefiner: dst[i].Clear(), dst[i].AddWithWeight(src[j] or dst[j], w).
struct ConstRef {
  const Vec3* p;
};
struct Ref {
  Vec3* p;
  void Clear(void* /*unused*/ = nullptr) const { *p = Vec3(0.0); }
  void AddWithWeight(const ConstRef& s, double w) const { *p += w * *s.p; }
  void AddWithWeight(const Ref& s, double w) const { *p += w * *s.p; }
};
struct Source {
  const Vec3* base;
  ConstRef operator[](int i) const { return {base + i}; }
};
struct Target {
  Vec3* base;
  Ref operator[](int i) const { return {base + i}; }
};

}  // namespace

struct SubdivisionLevels::Impl {
  std::unique_ptr<Far::TopologyRefiner> refiner;
  SubdivisionScheme scheme = SubdivisionScheme::CatmullClark;
  int levels = 0;
  std::vector<VertexId> control_vertices;
  std::uint64_t control_version = 0;
  // Per level: topology (as PolygonMesh index arrays) and the first vertex in `points`.
  std::vector<BigVector<std::uint32_t>> indices;
  std::vector<BigVector<std::uint32_t>> offsets;
  std::vector<std::size_t> first_vertex;  // levels + 2 entries
  BigVector<Vec3> points;                 // every level's vertices, level after level

  void interpolate() {
    const Far::PrimvarRefinerReal<double> primvar(*refiner);
    for (int level = 1; level <= levels; ++level) {
      const Source src{points.data() + first_vertex[static_cast<std::size_t>(level - 1)]};
      Target dst{points.data() + first_vertex[static_cast<std::size_t>(level)]};
      primvar.Interpolate(level, src, dst);
    }
  }
  void check_level(int level, const char* what) const {
    if (level < 0 || level > levels) {
      throw InputError(std::string("SubdivisionLevels::") + what + ": level " +
                       std::to_string(level) + " is not in 0.." + std::to_string(levels));
    }
  }
};

SubdivisionLevels::SubdivisionLevels(const Dlfl& control, const SubdivisionOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (options.levels < 0 || options.levels > 8) {
    throw InputError("SubdivisionLevels: levels must be 0 to 8 (got " +
                     std::to_string(options.levels) + ")");
  }
  ExportedPolygons exported = export_polygons(control);
  const PolygonMesh& poly = exported.polygons;
  if (poly.face_count() == 0) throw InputError("SubdivisionLevels: the control mesh has no faces");
  bool all_triangles = true;
  std::vector<int> verts_per_face(poly.face_count());
  for (std::size_t f = 0; f < poly.face_count(); ++f) {
    verts_per_face[f] = static_cast<int>(poly.face(f).size());
    all_triangles = all_triangles && verts_per_face[f] == 3;
  }
  m.scheme = options.scheme;
  if (m.scheme == SubdivisionScheme::Automatic) {
    m.scheme = all_triangles ? SubdivisionScheme::Loop : SubdivisionScheme::CatmullClark;
  }
  if (m.scheme == SubdivisionScheme::Loop && !all_triangles) {
    throw InputError(
        "SubdivisionLevels: the Loop scheme needs triangles; the control mesh has "
        "other polygons (use Catmull-Clark)");
  }
  m.levels = options.levels;
  m.control_vertices = std::move(exported.vertex_of_position);
  m.control_version = control.topology_version();

  Far::TopologyDescriptor desc;
  desc.numVertices = static_cast<int>(poly.positions.size());
  desc.numFaces = static_cast<int>(poly.face_count());
  desc.numVertsPerFace = verts_per_face.data();
  static_assert(sizeof(Far::Index) == sizeof(std::uint32_t));
  std::vector<Far::Index> face_indices(poly.indices.begin(), poly.indices.end());
  desc.vertIndicesPerFace = face_indices.data();

  Sdc::Options sdc;
  sdc.SetVtxBoundaryInterpolation(options.sharp_boundary_corners
                                      ? Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER
                                      : Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  const Sdc::SchemeType type =
      m.scheme == SubdivisionScheme::Loop ? Sdc::SCHEME_LOOP : Sdc::SCHEME_CATMARK;
  osd_message.clear();
  Far::SetErrorCallback(keep_error);
  Far::SetWarningCallback(ignore_warning);
  m.refiner.reset(Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Create(
      desc, Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Options(type, sdc)));
  if (!m.refiner) {
    throw InputError("SubdivisionLevels: OpenSubdiv refused the control mesh" +
                     (osd_message.empty() ? std::string() : ": " + osd_message));
  }
  if (m.levels > 0) m.refiner->RefineUniform(Far::TopologyRefiner::UniformOptions(m.levels));

  // Topology of every level, read once.
  m.first_vertex.assign(static_cast<std::size_t>(m.levels) + 2, 0);
  m.indices.resize(static_cast<std::size_t>(m.levels) + 1);
  m.offsets.resize(static_cast<std::size_t>(m.levels) + 1);
  for (int level = 0; level <= m.levels; ++level) {
    const auto l = static_cast<std::size_t>(level);
    const Far::TopologyLevel& tl = m.refiner->GetLevel(level);
    m.first_vertex[l + 1] = m.first_vertex[l] + static_cast<std::size_t>(tl.GetNumVertices());
    auto& idx = m.indices[l];
    auto& off = m.offsets[l];
    off.reserve(static_cast<std::size_t>(tl.GetNumFaces()) + 1);
    off.push_back(0);
    for (int f = 0; f < tl.GetNumFaces(); ++f) {
      const Far::ConstIndexArray fv = tl.GetFaceVertices(f);
      for (int i = 0; i < fv.size(); ++i)
        idx.push_back(static_cast<std::uint32_t>(fv[i]));
      off.push_back(static_cast<std::uint32_t>(idx.size()));
    }
  }
  m.points.resize(m.first_vertex.back());
  std::copy(poly.positions.begin(), poly.positions.end(), m.points.begin());
  m.interpolate();
}

SubdivisionLevels::~SubdivisionLevels() = default;
SubdivisionLevels::SubdivisionLevels(SubdivisionLevels&&) noexcept = default;
SubdivisionLevels& SubdivisionLevels::operator=(SubdivisionLevels&&) noexcept = default;

int SubdivisionLevels::levels() const {
  return impl_->levels;
}
SubdivisionScheme SubdivisionLevels::scheme() const {
  return impl_->scheme;
}
const std::vector<VertexId>& SubdivisionLevels::control_vertices() const {
  return impl_->control_vertices;
}

std::size_t SubdivisionLevels::vertex_count(int level) const {
  impl_->check_level(level, "vertex_count");
  const auto l = static_cast<std::size_t>(level);
  return impl_->first_vertex[l + 1] - impl_->first_vertex[l];
}

std::size_t SubdivisionLevels::face_count(int level) const {
  impl_->check_level(level, "face_count");
  return impl_->offsets[static_cast<std::size_t>(level)].size() - 1;
}

void SubdivisionLevels::update(const Dlfl& control) {
  Impl& m = *impl_;
  if (control.topology_version() != m.control_version) {
    throw TopologyError(
        "SubdivisionLevels::update: the control mesh's topology changed since the levels were "
        "built (build new levels)");
  }
  for (std::size_t i = 0; i < m.control_vertices.size(); ++i)
    m.points[i] = control.position(m.control_vertices[i]);
  m.interpolate();
}

void SubdivisionLevels::update(std::span<const Dlfl::Vec3> control_positions) {
  Impl& m = *impl_;
  if (control_positions.size() != m.control_vertices.size()) {
    throw InputError("SubdivisionLevels::update: " + std::to_string(control_positions.size()) +
                     " positions for " + std::to_string(m.control_vertices.size()) +
                     " control vertices");
  }
  std::copy(control_positions.begin(), control_positions.end(), m.points.begin());
  m.interpolate();
}

std::span<const Dlfl::Vec3> SubdivisionLevels::positions(int level) const {
  impl_->check_level(level, "positions");
  const auto l = static_cast<std::size_t>(level);
  return {impl_->points.data() + impl_->first_vertex[l],
          impl_->first_vertex[l + 1] - impl_->first_vertex[l]};
}

PolygonMesh SubdivisionLevels::level_mesh(int level) const {
  impl_->check_level(level, "level_mesh");
  const auto l = static_cast<std::size_t>(level);
  PolygonMesh out;
  const auto pts = positions(level);
  out.positions.assign(pts.begin(), pts.end());
  out.indices = impl_->indices[l];
  out.offsets = impl_->offsets[l];
  return out;
}

Dlfl SubdivisionLevels::build_level(int level) const {
  const PolygonMesh mesh = level_mesh(level);
  try {
    return build_oriented_manifold(mesh);
  } catch (const InputError&) {
    // Non-manifold vertices or edges (passed through from the control mesh): the general import.
    return std::move(import_polygons(mesh, true).mesh);
  }
}

}  // namespace bisturi::lod
