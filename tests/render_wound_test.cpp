// Incisions seen in the frame: a cut through the shell of a solid (sim::cut_surface, its lips
// held apart as tissue tension does) shows the inner side of the surface in the interior
// material, along the cut and nowhere else, and never the background through a hole.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/soft_body.h"
#include "render_test_support.h"

namespace bisturi::render {
namespace {

using testing::Capture;
using testing::RendererFixture;

constexpr std::uint32_t kSize = 256;
const glm::dvec3 kCentre(0.0, 0.0, -200.0);
constexpr double kRadius = 40.0;

/// Moves each lip of the incision `gap_mm` / 2 away from the cut plane (y = 0): each copy of a
/// path vertex goes to the side its faces lie on.
void open_lips(Dlfl& mesh, const sim::CutResult& cut, double gap_mm) {
  std::vector<double> side(mesh.vertex_capacity(), 0.0);
  std::vector<char> lip(mesh.vertex_capacity(), 0);
  for (const VertexId v : cut.path)
    lip[v.idx] = 1;
  for (const VertexId v : cut.new_vertices)
    lip[v.idx] = 1;
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId face{f};
    if (!mesh.alive(face) || mesh.is_bounding(face)) continue;
    glm::dvec3 centroid(0.0);
    int n = 0;
    const CornerId first = mesh.first_corner(face);
    CornerId c = first;
    do {
      centroid += mesh.position(mesh.vertex(c));
      ++n;
      c = mesh.next(c);
    } while (c != first);
    centroid /= n;
    c = first;
    do {
      const VertexId v = mesh.vertex(c);
      if (lip[v.idx]) side[v.idx] += centroid.y - mesh.position(v).y;
      c = mesh.next(c);
    } while (c != first);
  }
  for (std::uint32_t v = 0; v < mesh.vertex_capacity(); ++v) {
    if (!lip[v] || side[v] == 0.0) continue;
    glm::dvec3 p = mesh.position(VertexId{v});
    p.y += (side[v] > 0.0 ? 0.5 : -0.5) * gap_mm;
    mesh.set_position(VertexId{v}, p);
  }
}

bool background(const std::uint8_t* px) {
  return px[0] == 0 && px[1] == 0 && px[2] == 0;
}
/// The interior material's hue: red well above green and blue (the outside is a pinker tissue).
bool interior_hue(const std::uint8_t* px) {
  return px[0] > 20 && px[1] < 0.55 * px[0] && px[2] < 0.55 * px[0];
}

class RenderWoundTest : public RendererFixture {};

TEST_F(RenderWoundTest, AnOpenedIncisionShowsTheInteriorMaterialAlongItsPathOnly) {
  RendererOptions options;
  options.level_of_detail = false;  // the same level before and after: differences are the cut's
  options.levels.derived_levels = false;
  options.clear_colour = glm::vec3(0.0f);
  auto* r = make(options, kSize);
  REQUIRE_RENDERER(r);

  sim::SoftBody body(testing::sphere_mm(kCentre, kRadius, 48), sim::Material{});
  const SolidId id = r->add_solid(body.mesh());
  Capture before, after;
  r->set_sink(&before);
  r->render(testing::at_origin());
  r->flush();
  ASSERT_EQ(before.frames, 1u);

  // Across the front of the sphere, facing the eyes: an arc in the plane y = 0 (metres).
  std::vector<glm::dvec3> blade;
  for (int i = 0; i <= 8; ++i) {
    const double a = -0.55 + 1.1 * i / 8.0;
    blade.push_back(1e-3 * (kCentre + kRadius * glm::dvec3(std::sin(a), 0.0, std::cos(a))));
  }
  const sim::CutResult cut = sim::cut_surface(body, blade);
  ASSERT_TRUE(validate(body.mesh()).ok());
  ASSERT_GE(cut.new_vertices.size(), 4u);
  Dlfl opened = body.mesh();
  open_lips(opened, cut, 8.0);
  r->update_solid(id, opened);
  r->set_sink(&after);
  r->render(testing::at_origin());
  r->flush();
  ASSERT_EQ(after.frames, 1u);

  const HeadsetDescription& h = r->options().headset;
  for (int e = 0; e < 2; ++e) {
    std::vector<glm::dvec2> path;
    for (const VertexId v : cut.path)
      path.push_back(testing::project(h, testing::at_origin(), e, body.mesh().position(v)));
    std::size_t changed = 0, changed_far = 0, interior = 0, see_through = 0, interior_before = 0;
    for (std::uint32_t y = 0; y < kSize; ++y) {
      for (std::uint32_t x = 0; x < kSize; ++x) {
        const std::uint8_t* a = before.at(e, x, y);
        const std::uint8_t* b = after.at(e, x, y);
        interior_before += interior_hue(a);
        const bool differs =
            std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) > 6;
        if (!differs) continue;
        ++changed;
        const double d = testing::distance_to_polyline(path, {x + 0.5, y + 0.5});
        if (d > 14.0) ++changed_far;  // the lips moved 4 mm, about 3 pixels at 160 mm
        interior += interior_hue(b);
        see_through += !background(a) && background(b);
      }
    }
    EXPECT_EQ(interior_before, 0u) << "eye " << e;
    EXPECT_GT(interior, 150u) << "eye " << e << ": " << changed << " pixels changed";
    EXPECT_EQ(changed_far, 0u) << "eye " << e << ": " << changed << " pixels changed";
    EXPECT_EQ(see_through, 0u) << "eye " << e << ": the background shows through the cut";
  }
}

}  // namespace
}  // namespace bisturi::render
