// The default scripted procedure (see procedure.h).

#include "bisturi/runtime/session/procedure.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>
#include <glm/vec3.hpp>

#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/sim/units.h"

namespace bisturi::runtime {

namespace {

struct Box {
  glm::dvec3 lo{std::numeric_limits<double>::infinity()};
  glm::dvec3 hi{-std::numeric_limits<double>::infinity()};
  [[nodiscard]] glm::dvec3 centre() const { return (lo + hi) * 0.5; }
};

Box bounds(const Dlfl& mesh) {
  Box b;
  for (std::size_t i = 0; i < mesh.vertex_capacity(); ++i) {
    const VertexId v{static_cast<std::uint32_t>(i)};
    if (!mesh.alive(v)) continue;
    b.lo = glm::min(b.lo, mesh.position(v));
    b.hi = glm::max(b.hi, mesh.position(v));
  }
  return b;
}

devices::Vec3 to_metres(const glm::dvec3& mm) {
  const glm::dvec3 m = sim::scene_to_sim(mm);
  return {m.x, m.y, m.z};
}

glm::dvec3 vec(const std::array<double, 3>& a) {
  return {a[0], a[1], a[2]};
}

/// The targets a scene without a [procedure] table gets: the top of the first solid, the wall
/// of the second facing the viewer (anterior, -y) halfway up, and a 24 mm cut across the top.
ProcedureDescription targets_from_bounds(const Box& first, const Box& second) {
  ProcedureDescription d;
  const glm::dvec3 top(first.centre().x, first.centre().y, first.hi.z);
  const glm::dvec3 wall(second.centre().x, second.lo.y, second.centre().z);
  d.palpate_mm = {top.x, top.y, top.z};
  d.grasp_mm = {wall.x, wall.y, wall.z};
  d.cut_from_mm = {top.x - 12.0, top.y, top.z};
  d.cut_to_mm = {top.x + 12.0, top.y, top.z};
  return d;
}

}  // namespace

namespace {

struct Targets {
  Box first, second;
  ProcedureDescription d;
};

Targets targets_of(const std::vector<BuiltSolid>& solids) {
  if (solids.empty()) throw SceneFileError("the scripted procedure needs at least one solid");
  Targets t;
  t.first = bounds(solids.front().mesh);
  t.second = bounds(solids.size() > 1 ? solids[1].mesh : solids.front().mesh);
  const SceneDescription* scene = solids.front().scene;
  t.d = scene != nullptr && scene->procedure ? *scene->procedure
                                             : targets_from_bounds(t.first, t.second);
  return t;
}

/// Where the assisting hand takes hold: the outermost vertex of the first solid (along the cut's
/// normal) within 2 mm of the line through `near` along that normal, else `near`.
glm::dvec3 surface_point(const Dlfl& mesh, const glm::dvec3& near, const glm::dvec3& normal) {
  glm::dvec3 best = near;
  double best_height = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < mesh.vertex_capacity(); ++i) {
    const VertexId v{static_cast<std::uint32_t>(i)};
    if (!mesh.alive(v)) continue;
    const glm::dvec3 p = mesh.position(v);
    const double height = glm::dot(p - near, normal);
    if (glm::length((p - near) - height * normal) > 2.0 || height <= best_height) continue;
    best = p;
    best_height = height;
  }
  return best;
}

int button_for(const std::vector<devices::ButtonUse>& buttons, devices::ButtonUse use,
               int fallback) {
  const auto it = std::find(buttons.begin(), buttons.end(), use);
  return it != buttons.end() ? static_cast<int>(it - buttons.begin()) : fallback;
}

devices::DeviceScript hold_script(const std::vector<BuiltSolid>& solids,
                                  devices::Nanoseconds duration, std::size_t joints,
                                  const std::vector<devices::ButtonUse>& buttons) {
  const Targets t = targets_of(solids);
  const glm::dvec3 cut_a = vec(t.d.cut_from_mm), cut_b = vec(t.d.cut_to_mm);
  const glm::dvec3 cn = glm::normalize(vec(t.d.cut_normal));
  glm::dvec3 side = glm::cross(cn, cut_b - cut_a);
  side = glm::length(side) > 1e-9 ? glm::normalize(side) : glm::dvec3(0.0, -1.0, 0.0);
  const glm::dvec3 hold =
      surface_point(solids.front().mesh, 0.5 * (cut_a + cut_b) + 10.0 * side, cn) - 1.0 * cn;
  const glm::dvec3 held = hold + 4.0 * cn + 2.0 * side;
  devices::DeviceScript script;
  const double total = static_cast<double>(duration.count());
  const auto at = [total](double fraction) {
    return devices::Nanoseconds{static_cast<std::int64_t>(std::llround(fraction * total))};
  };
  const auto key = [&](double fraction, const glm::dvec3& tip_mm, double joints_rad) {
    devices::MotionKey k;
    k.t = at(fraction);
    k.pose.position_m = to_metres(tip_mm);
    k.joints_rad.assign(joints, joints_rad);
    script.motion.push_back(k);
  };
  const double open = 0.1, closed = 1.1;
  key(0.00, hold + 25.0 * cn + 10.0 * side, open);
  key(0.55, hold + 6.0 * cn, open);
  key(0.62, hold, open);
  key(0.65, hold, closed);  // takes hold
  key(0.72, held, closed);  // lifts and draws the tissue from the path
  key(0.93, held, closed);  // through the cut
  key(0.95, held, open);    // lets go
  key(1.00, hold + 25.0 * cn + 10.0 * side, open);
  const int grasp_button = button_for(buttons, devices::ButtonUse::Grasp, -1);
  if (grasp_button >= 0) {
    script.presses.push_back({at(0.65), static_cast<std::uint32_t>(grasp_button), true});
    script.presses.push_back({at(0.95), static_cast<std::uint32_t>(grasp_button), false});
  }
  return script;
}

devices::DeviceScript default_script(const Targets& t, devices::Nanoseconds duration,
                                     std::size_t hand_joints,
                                     const std::vector<devices::ButtonUse>& buttons) {
  const ProcedureDescription& d = t.d;
  const glm::dvec3 palpate = vec(d.palpate_mm), pn = vec(d.palpate_normal);
  const glm::dvec3 grasp = vec(d.grasp_mm), gn = vec(d.grasp_normal);
  const glm::dvec3 cut_a = vec(d.cut_from_mm), cut_b = vec(d.cut_to_mm), cn = vec(d.cut_normal);
  devices::DeviceScript hand;
  const double total = static_cast<double>(duration.count());
  const auto at = [total](double fraction) {
    return devices::Nanoseconds{static_cast<std::int64_t>(std::llround(fraction * total))};
  };
  // The scalpel's blade runs along the pose's +z from the tip: during the cut it points out of
  // the surface along the cut's normal, so that it crosses the surface as it sweeps (upright for
  // the default normal +z, the pose's identity).
  const glm::dquat blade = glm::rotation(glm::dvec3(0.0, 0.0, 1.0), cn);
  const auto key = [&](double fraction, const glm::dvec3& tip_mm, double joints_rad,
                       bool cutting = false) {
    devices::MotionKey k;
    k.t = at(fraction);
    k.pose.position_m = to_metres(tip_mm);
    if (cutting) k.pose.orientation = {blade.w, blade.x, blade.y, blade.z};
    k.joints_rad.assign(hand_joints, joints_rad);
    hand.motion.push_back(k);
  };
  const double open = 0.1, closed = 1.1;
  key(0.00, palpate + 30.0 * pn, open);
  key(0.12, palpate + 4.0 * pn, open);                 // approach
  key(0.20, palpate - d.palpate_depth_mm * pn, open);  // palpate: press in
  key(0.26, palpate + 4.0 * pn, open);                 // and let go
  key(0.30, palpate + 30.0 * pn, open);  // back out, and round to the front of the vessel
  key(0.33, grasp + 30.0 * gn, open);
  key(0.36, grasp + 10.0 * gn, open);
  key(0.42, grasp - 1.0 * gn, open);
  key(0.46, grasp - 1.0 * gn, closed);        // grasp
  key(0.56, grasp + d.pull_mm * gn, closed);  // pull
  key(0.60, grasp - 0.5 * gn, closed);
  key(0.63, grasp - 0.5 * gn, open);  // release
  key(0.68, grasp + 10.0 * gn, open);
  key(0.74, cut_a + 4.0 * cn, open, true);
  key(0.78, cut_a - d.cut_depth_mm * cn, open, true);  // blade in
  key(0.90, cut_b - d.cut_depth_mm * cn, open, true);  // sweep
  key(0.96, cut_b + 20.0 * cn, open, true);
  const int cut_button = button_for(buttons, devices::ButtonUse::Cut, buttons.empty() ? 0 : -1);
  const int grasp_button = button_for(buttons, devices::ButtonUse::Grasp, -1);
  if (grasp_button >= 0) {  // held while the hand is closed
    hand.presses.push_back({at(0.46), static_cast<std::uint32_t>(grasp_button), true});
    hand.presses.push_back({at(0.63), static_cast<std::uint32_t>(grasp_button), false});
  }
  if (cut_button >= 0) {
    hand.presses.push_back({at(0.785), static_cast<std::uint32_t>(cut_button), true});
    hand.presses.push_back({at(0.905), static_cast<std::uint32_t>(cut_button), false});
  }
  return hand;
}

}  // namespace

devices::DeviceScript make_hand_script(const std::string& script,
                                       const std::vector<BuiltSolid>& solids,
                                       devices::Nanoseconds duration, std::size_t joints,
                                       const std::vector<devices::ButtonUse>& buttons) {
  if (script == "default") return default_script(targets_of(solids), duration, joints, buttons);
  if (script == "hold") return hold_script(solids, duration, joints, buttons);
  throw SceneFileError("device script '" + script +
                       "': the scripts are \"default\" (the whole procedure) and \"hold\" (an "
                       "assisting hand holding the tissue beside the cut)");
}

Procedure make_procedure(const std::string& script, const std::vector<BuiltSolid>& solids,
                         devices::Nanoseconds duration, std::size_t hand_joints,
                         const std::vector<devices::ButtonUse>& buttons) {
  Procedure p;
  p.first_hand = make_hand_script(script, solids, duration, hand_joints, buttons);
  const Targets t = targets_of(solids);
  const Box& first = t.first;
  const Box& second = t.second;
  const double total = static_cast<double>(duration.count());
  const auto at = [total](double fraction) {
    return devices::Nanoseconds{static_cast<std::int64_t>(std::llround(fraction * total))};
  };
  p.phases = {{"approach", at(0.0), at(0.12)},
              {"palpate", at(0.12), at(0.26)},
              {"grasp", at(0.36), at(0.63)},
              {"cut", at(0.74), at(0.905)}};

  // The head: in front of the scene (anterior), above it, swaying a little from side to side.
  const glm::dvec3 centre = (glm::min(first.lo, second.lo) + glm::max(first.hi, second.hi)) * 0.5;
  const double size = glm::length(glm::max(first.hi, second.hi) - glm::min(first.lo, second.lo));
  // Near enough that the solids' bounding sphere spans four fifths of the narrowest half field of
  // view (the solids themselves less): the field fills a working share of each eye.
  double half_fov_deg = 45.0;
  if (const SceneDescription* scene = solids.front().scene)
    half_fov_deg = *std::min_element(scene->headset.fov_deg.begin(), scene->headset.fov_deg.end());
  const double distance = 0.5 * size / std::sin(glm::radians(0.8 * half_fov_deg));
  const glm::dvec3 away = glm::normalize(glm::dvec3(0.0, -1.6, 0.9));
  for (int i = 0; i <= 8; ++i) {
    const double f = i / 8.0;
    const glm::dvec3 eye = centre + distance * away +
                           glm::dvec3(0.08 * distance * std::sin(f * 6.283185307179586), 0.0, 0.0);
    const render::HeadPose look = render::look_at(eye, centre, {0.0, 0.0, 1.0});
    devices::MotionKey k;
    k.t = at(f);
    k.pose.position_m = to_metres(eye);
    k.pose.orientation = {look.orientation.w, look.orientation.x, look.orientation.y,
                          look.orientation.z};
    p.head.motion.push_back(k);
  }
  return p;
}

}  // namespace bisturi::runtime
