// One haptic tick of the session's simulation (see session_sim.h).

#include "bisturi/runtime/session/session_sim.h"

#include "blood_worker.h"
#include "free_core.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <thread>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/errors.h"
#include "bisturi/sim/pulse.h"
#include "bisturi/sim/units.h"
#include "hand_model.h"

namespace bisturi::runtime {

const char* to_string(SessionEventKind kind) {
  switch (kind) {
    case SessionEventKind::Contact:
      return "contact";
    case SessionEventKind::GraspClosed:
      return "grasp";
    case SessionEventKind::GraspReleased:
      return "release";
    case SessionEventKind::CutStarted:
      return "cut-start";
    case SessionEventKind::Cut:
      return "cut";
  }
  return "?";
}

namespace {

/// The blood's threads on a machine with `cores`: a helper when a core is left free after the
/// haptic loop, the renderer, the tissue and the blood's own thread; on fewer cores it would
/// only take turns with the blood's thread and wait for it (sim/blood.h keeps the same bits).
unsigned blood_threads_for(unsigned cores) {
  constexpr unsigned kBusyThreads = 4;
  return cores > kBusyThreads ? 2u : 1u;
}

sim::Material to_material(const MaterialDescription& m) {
  sim::Material out;
  out.structural_N_per_m = m.stiffness_N_per_m;
  out.shear_N_per_m = m.stiffness_N_per_m * 0.25;
  out.bending_N_per_m = m.stiffness_N_per_m * 0.05;
  out.spring_damping_N_s_per_m = m.damping_N_s_per_m;
  out.density_kg_per_m3 = m.density_kg_per_m3;
  out.bulk_modulus_Pa = m.bulk_modulus_Pa;  // calibrated from the modulus, or the default
  return out;
}

glm::dvec3 to_glm(const devices::Vec3& v) {
  return {v.x, v.y, v.z};
}

}  // namespace

namespace {

double first_haptic_limit_N(const SceneDescription& scene) {
  for (const DeviceDescription& d : scene.devices) {
    if (d.role == DeviceDescription::Role::Haptic) return d.max_force_N;
  }
  return 3.0;
}

HandSetup hand_of(const SceneDescription& scene, std::vector<devices::ForceChannel> channels,
                  const SessionSimOptions& options) {
  return {std::move(channels),   options.device_frame, options.device_spec,
          options.channel_roles, options.button_uses,  first_haptic_limit_N(scene)};
}

}  // namespace

SessionSim::~SessionSim() = default;
SessionSim::SessionSim(SessionSim&&) noexcept = default;
SessionSim& SessionSim::operator=(SessionSim&&) noexcept = default;

SessionSim::SessionSim(const SceneDescription& scene, std::vector<BuiltSolid> solids,
                       std::vector<devices::ForceChannel> channels,
                       const SessionSimOptions& options)
    : SessionSim(scene, std::move(solids), {hand_of(scene, std::move(channels), options)},
                 options) {}

SessionSim::SessionSim(const SceneDescription& scene, std::vector<BuiltSolid> solids,
                       std::vector<HandSetup> hands, const SessionSimOptions& options)
    : options_(options) {
  if (hands.empty()) throw SceneFileError(scene.name + ": a session needs at least one hand");
  for (const InstrumentDescription& in : scene.instruments) {
    if (in.kind == InstrumentDescription::Kind::Probe) {
      world_.options().haptic.probe_radius_m = in.radius_mm * sim::kMetresPerMillimetre;
      probe_length_mm_ = in.length_mm;
    } else if (in.kind == InstrumentDescription::Kind::Grasper) {
      jaw_radius_mm_ = in.radius_mm;
    } else {
      options_.blade_length_mm = in.length_mm;
    }
  }
  // The proxies clamp at the strongest hand's limit; each hand's command at its own.
  double max_force_N = 0.0;
  for (const HandSetup& h : hands)
    max_force_N = std::max(max_force_N, h.max_force_N);
  world_.options().haptic.max_force_N = max_force_N;
  world_.options().haptic.continuous = scene.simulation.continuous_collision;
  // The coupling spring is what the hand feels in contact: never stiffer than a device renders
  // (one spring for every hand, the softest device's).
  for (const HandSetup& h : hands) {
    const double device_k = h.device_spec.max_stiffness_N_per_m;
    if (device_k > 0.0) {
      world_.options().haptic.coupling_N_per_m =
          std::min(world_.options().haptic.coupling_N_per_m, device_k);
    }
  }
  coupling_N_per_m_ = world_.options().haptic.coupling_N_per_m;
  haptic_hz_ = scene.rates.haptic_hz;
  heart_rate_hz_ = scene.physiology.heart_rate_bpm / 60.0;
  breathing_period_s_ = scene.physiology.breathing_period_s;
  world_.options().integrator.dt_s = 1.0 / haptic_hz_;
  world_.options().integrator.far_field_interval = scene.simulation.far_field_interval;
  world_.options().integrator.threads = std::max(1u, options_.tissue_threads);
  for (BuiltSolid& s : solids) {
    const SolidDescription& d = *s.description;
    sim::SoftBody body(std::move(s.mesh), to_material(d.material));
    const Dlfl& mesh = body.mesh();
    for (std::size_t i = 0; i < mesh.vertex_capacity(); ++i) {
      const VertexId v{static_cast<std::uint32_t>(i)};
      if (!mesh.alive(v)) continue;
      bool anchored = !d.simulate;
      const glm::dvec3 p = mesh.position(v);
      for (const AnchorDescription& a : d.anchors) {
        const glm::dvec3 n = glm::normalize(glm::dvec3(a.normal[0], a.normal[1], a.normal[2]));
        const glm::dvec3 q(a.point_mm[0], a.point_mm[1], a.point_mm[2]);
        anchored = anchored || glm::dot(p - q, n) <= a.distance_mm;
      }
      if (anchored) body.set_anchored(v, true);
    }
    names_.push_back(d.name);
    const std::uint32_t index = world_.add_body(std::move(body));
    volume_build_ms_.push_back(0.0);
    pulse_pressure_Pa_.push_back(
        d.pulse_mmHg ? ((*d.pulse_mmHg)[1] - (*d.pulse_mmHg)[0]) * sim::kPascalPerMmHg : 0.0);
    diastolic_Pa_.push_back(d.pulse_mmHg ? (*d.pulse_mmHg)[0] * sim::kPascalPerMmHg : 0.0);
    breathing_m_.push_back(
        d.breathing_mm ? sim::scene_to_sim(glm::dvec3((*d.breathing_mm)[0], (*d.breathing_mm)[1],
                                                      (*d.breathing_mm)[2]))
                       : glm::dvec3(0.0));
    // A volume by default only, not asked for, stays a membrane when its surface is open.
    const bool open_by_default = !d.model_given && !world_.body(index).closed();
    if (d.model == SolidDescription::Model::Volume && d.simulate && !open_by_default) {
      sim::VolumeOptions volume;
      volume.cell_m = d.cell_mm * sim::kMetresPerMillimetre;
      volume.weight_supported = d.supported;
      volume.resting_tension_Pa = d.tension_Pa;
      volume.cut_refine_factor = static_cast<std::uint32_t>(d.cut_refine);
      if (d.refine) {
        volume.refine_factor = static_cast<std::uint32_t>(d.refine->factor);
        volume.refine_centre_m = sim::scene_to_sim(
            glm::dvec3(d.refine->centre_mm[0], d.refine->centre_mm[1], d.refine->centre_mm[2]));
        volume.refine_half_width_m = d.refine->half_width_mm * sim::kMetresPerMillimetre;
        volume.refine_follows = d.refine->follow;
      }
      volume.material = {d.material.youngs_modulus_kPa, d.material.poisson_ratio,
                         d.material.density_kg_per_m3, d.material.retardation_time_s};
      try {
        const auto begin = std::chrono::steady_clock::now();
        world_.set_volume(index, volume);
        volume_build_ms_.back() =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin)
                .count();
      } catch (const sim::SimInputError& e) {
        throw sim::SimInputError("solid '" + d.name + "': " + e.what());
      }
    }
  }
  // Everything the first step would build lazily (solver structure, BVHs, scratch) is built now,
  // before the haptic clock starts: tick 1 costs what tick 2 costs.
  world_.prepare();
  // The blood runs on every solid and on a tray 2 mm below the lowest (the table's drapes), and
  // drains off the field: the solids' box across, widened by its size each way.
  sim::BloodOptions& blood = blood_options_;
  blood.density_kg_per_m3 = scene.physiology.blood_density_kg_per_m3;
  blood.viscosity = scene.physiology.blood_viscosity;
  blood.max_particles = static_cast<std::size_t>(scene.physiology.blood_max_particles);
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (std::size_t b = 0; b < world_.body_count(); ++b) {
    const sim::SoftBody& body = world_.body(static_cast<std::uint32_t>(b));
    for (const glm::dvec3& p : body.positions()) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  }
  if (lo.x <= hi.x) {
    blood.floor_z_m = lo.z - 0.002;
    blood.field_min_m = lo - (hi - lo);
    blood.field_max_m = hi + (hi - lo);
  }
  no_blood_ = sim::Blood(blood);
  blood.threads = blood_threads_for(std::thread::hardware_concurrency());
  blood.helper_start = [] { run_only_on_a_free_core(true); };
  out_.other_hands.resize(hands.size() - 1);
  for (std::size_t i = 0; i < hands.size(); ++i) {
    Hand h;
    h.setup = std::move(hands[i]);
    devices::Capabilities shape;
    shape.force_channels = h.setup.channels;
    const devices::ChannelLayout layout{h.setup.channel_roles, {}};
    h.roles = layout.roles(shape);
    for (std::size_t c = 0; c < h.setup.channels.size(); ++c) {
      h.command_size += h.setup.channels[c].components;
      if (h.roles[c].use == devices::ChannelUse::Finger)
        h.fingers = std::max<std::size_t>(h.fingers, h.roles[c].finger + 1u);
    }
    const double device_k = h.setup.device_spec.max_stiffness_N_per_m;
    h.finger_stiffness_N_per_m = device_k > 0.0
                                     ? std::min(options_.finger_stiffness_N_per_m, device_k)
                                     : options_.finger_stiffness_N_per_m;
    if (!h.setup.button_uses.empty()) {
      h.cut_buttons = devices::buttons_with(h.setup.button_uses, devices::ButtonUse::Cut);
      h.grasp_buttons = devices::buttons_with(h.setup.button_uses, devices::ButtonUse::Grasp);
    }
    h.finger_touch.assign(h.fingers, FingerTouch{});
    HandOutput& out = out_.hand(i);
    out.command_N.assign(h.command_size, 0.0);
    out.finger_contact_N.assign(h.fingers, 0.0);
    hands_.push_back(std::move(h));
  }
  tips_m_.resize(hands_.size());
  haptic_out_.resize(hands_.size());
  const auto has_lumen = [](double pressure_Pa) { return pressure_Pa > 0.0; };
  if (std::any_of(pulse_pressure_Pa_.begin(), pulse_pressure_Pa_.end(), has_lumen) ||
      std::any_of(diastolic_Pa_.begin(), diastolic_Pa_.end(), has_lumen))
    blood_worker_ = std::make_unique<BloodWorker>(blood_options_, world_);
}

std::vector<devices::ForceChannel> SessionSim::guard_channels(std::size_t hand) const {
  const Hand& h = hands_[hand];
  std::vector<devices::ForceChannel> channels = h.setup.channels;
  for (devices::ForceChannel& c : channels) {
    if (!c.unitless) c.max_force_N = std::min(c.max_force_N, h.setup.max_force_N);
  }
  return channels;
}

glm::dvec3 SessionSim::tip_of(const devices::HapticState& state) {
  return state.end_effector_poses.empty() ? glm::dvec3(0.0)
                                          : to_glm(state.end_effector_poses.front().position_m);
}

void SessionSim::add_event(SessionEventKind kind, std::size_t hand, std::int32_t body,
                           std::string detail) {
  events_.push_back(
      SessionEvent{kind, ticks_, body, static_cast<std::uint32_t>(hand), std::move(detail)});
  ++out_.events;
}

std::int32_t SessionSim::nearest_body(const glm::dvec3& p_m) {
  // The body with a vertex closest to p (a linear pass, done once per grasp or cut).
  std::int32_t best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t b = 0; b < world_.body_count(); ++b) {
    const sim::SoftBody& x = world_.body(static_cast<std::uint32_t>(b));
    for (std::size_t i = 0; i < x.positions().size(); ++i) {
      if (x.masses()[i] <= 0.0) continue;
      const glm::dvec3 d = x.positions()[i] - p_m;
      const double dd = glm::dot(d, d);
      if (dd < best_d) {
        best_d = dd;
        best = static_cast<std::int32_t>(b);
      }
    }
  }
  return best;
}

const TickOutput& SessionSim::tick(const devices::HapticState& state, std::uint32_t ticks,
                                   bool blood_held) {
  return tick(std::span<const devices::HapticState>(&state, 1), ticks, blood_held);
}

const TickOutput& SessionSim::tick(std::span<const devices::HapticState> states,
                                   std::uint32_t ticks, bool blood_held) {
  if (states.size() != hands_.size())
    throw std::invalid_argument("SessionSim::tick: " + std::to_string(states.size()) +
                                " device states for " + std::to_string(hands_.size()) + " hands");
  ticks = std::max(1u, ticks);
  if (ticks != step_ticks_) {
    step_ticks_ = ticks;
    world_.options().integrator.dt_s = static_cast<double>(ticks) / haptic_hz_;
  }
  out_.events = 0;
  out_.topology_changed = false;
  for (std::size_t i = 0; i < hands_.size(); ++i) {
    Hand& hand = hands_[i];
    const devices::Pose pose = states[i].end_effector_poses.empty()
                                   ? devices::Pose{}
                                   : states[i].end_effector_poses.front();
    tips_m_[i] = to_glm(pose.position_m);
    out_.hand(i).tip_m = tips_m_[i];
    hand.orientation =
        glm::dquat(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
    hand.tip_mm = sim::sim_to_scene(tips_m_[i]);
    hand.blade_to_mm =
        hand.tip_mm + hand.orientation * glm::dvec3(0.0, 0.0, options_.blade_length_mm);
    update_grasp(i, states[i], tips_m_[i]);
    // While the scalpel cuts, and as it leaves the incision, the blade parts the tissue instead
    // of pushing it (no reaction on the surface; the hand still feels it).
    world_.set_probe(i, {hand.grasp_body, hand.cut_body < 0 && !hand.withdrawing});
  }

  apply_physiology(ticks);
  // The probes, tissue contact and the soft-tissue step, every hand's in one step.
  world_.step(tips_m_, haptic_out_);
  for (std::size_t i = 0; i < hands_.size(); ++i) {
    Hand& hand = hands_[i];
    const sim::HapticOutput& h = haptic_out_[i];
    HandOutput& out = out_.hand(i);
    out.force_N = h.force_N;
    out.contact = h.contact;
    out.contact_stiffness_N_per_m = contact_stiffness(h);
    out.patch_velocity_m_s = h.patch_velocity_m_s;
    // A new touch (not a flicker at the edge of one: 100 ticks without contact before it).
    if (h.contact && !hand.contact && ticks_ >= hand.last_contact_tick + 100)
      add_event(SessionEventKind::Contact, i, h.body, "");
    if (h.contact) hand.last_contact_tick = ticks_;
    hand.contact = h.contact;
    if (!h.contact) hand.withdrawing = false;
  }
  for (sim::SimEvent& e : world_.take_events()) {
    ++divergence_events_;
    // Kept for the report, up to a bound: a solid rolled back at every step must not grow it.
    if (divergences_.size() < kKeptDivergences) divergences_.push_back({ticks_, std::move(e)});
  }
  for (std::size_t i = 0; i < hands_.size(); ++i) {
    finger_contacts(hands_[i], out_.hand(i), tips_m_[i], states[i].finger_joint_angles_rad);
    update_scalpel(i, states[i], tips_m_[i]);
  }
  bleed(ticks, blood_held);
  for (std::size_t i = 0; i < hands_.size(); ++i) {
    HandOutput& out = out_.hand(i);
    out.grasping = hands_[i].grasp_body >= 0;
    out.cutting = hands_[i].cut_body >= 0;
    command_for(out_, i, tips_m_[i], out.command_N);
  }
  ticks_ += ticks;
  return out_;
}

void SessionSim::apply_physiology(std::uint32_t ticks) {
  // Session time from the ticks simulated, never a clock: a replay pulses and breathes the same.
  const double t_s = static_cast<double>(ticks_) / haptic_hz_;
  const double dt_s = static_cast<double>(ticks) / haptic_hz_;
  // Breathing: each breathing body's support goes to where the breath has it at the step's end
  // (0 at the end of expiration, the whole displacement at full inspiration, smoothly).
  const double breath =
      0.5 * (1.0 - std::cos(2.0 * 3.141592653589793 * (t_s + dt_s) / breathing_period_s_));
  for (std::size_t b = 0; b < breathing_m_.size(); ++b) {
    if (breathing_m_[b] == glm::dvec3(0.0)) continue;
    const auto i = static_cast<std::uint32_t>(b);
    const sim::VolumeBody* volume = world_.volume(i);
    if (volume == nullptr) continue;
    world_.move_support(i, (breath * breathing_m_[b] - volume->support_offset()) / dt_s);
  }
  const double beat = sim::cardiac_waveform(t_s * heart_rate_hz_);
  pulse_now_Pa_ = 0.0;
  for (std::size_t b = 0; b < pulse_pressure_Pa_.size(); ++b) {
    if (pulse_pressure_Pa_[b] <= 0.0) continue;
    pulse_now_Pa_ = pulse_pressure_Pa_[b] * beat;
    sim::apply_lumen_pressure(world_.body(static_cast<std::uint32_t>(b)), pulse_now_Pa_);
  }
}

void SessionSim::open_vessel(std::int32_t body, const std::vector<glm::dvec3>& points_m) {
  if (body < 0 || points_m.empty()) return;
  const auto lumen = static_cast<std::size_t>(body);
  if (pulse_pressure_Pa_[lumen] <= 0.0 && diastolic_Pa_[lumen] <= 0.0) return;  // no lumen pressure
  // The incision gapes about half a millimetre: its area is its length times that. Blood leaves
  // along the wall's outward normal at up to eight points along it.
  constexpr double kGap_m = 0.0005;
  constexpr std::size_t kMostSources = 8;
  Opening opening;
  opening.body = body;
  double length = 0.0;
  for (std::size_t i = 1; i < points_m.size(); ++i)
    length += glm::length(points_m[i] - points_m[i - 1]);
  opening.area_m2 = std::max(length, 0.001) * kGap_m;
  const auto b = static_cast<std::uint32_t>(body);
  const std::size_t stride = std::max<std::size_t>(1, points_m.size() / kMostSources);
  for (std::size_t i = 0; i < points_m.size(); i += stride) {
    const sim::SurfacePoint q = world_.bvh(b).closest_point(world_.body(b), points_m[i], 0.01);
    if (!q.found) continue;
    opening.sources.push_back({q.point_m, q.normal});
  }
  if (!opening.sources.empty()) openings_.push_back(std::move(opening));
}

void SessionSim::bleed(std::uint32_t ticks, bool held) {
  if (openings_.empty()) return;
  if (held) {
    // Its thread is behind: the blood's time stops (slow motion) rather than the tissue's
    // thread waiting for it, and the flow of these steps is not emitted.
    blood_held_s_ += static_cast<double>(ticks) / haptic_hz_;
    return;
  }
  blood_due_s_ += static_cast<double>(ticks) / haptic_hz_;
  if (blood_due_s_ < kBloodStep_s) return;
  std::size_t used = 0;
  const double t_s = static_cast<double>(ticks_) / haptic_hz_;
  const double beat = sim::cardiac_waveform(t_s * heart_rate_hz_);
  const double density = blood_options_.density_kg_per_m3;
  blood_flow_m3_s_ = 0.0;
  for (const Opening& o : openings_) {
    const auto b = static_cast<std::size_t>(o.body);
    // A grasper holding the vessel clamps it: no flow past its jaws.
    const bool clamped = std::any_of(hands_.begin(), hands_.end(),
                                     [&](const Hand& h) { return h.grasp_body == o.body; });
    if (clamped) continue;
    // Through the opening as through an orifice, its speed growing as the square root of the
    // lumen's pressure now over the blood's density (Torricelli), scaled so that 120 mmHg in
    // blood of 1060 kg/m^3 leaves at 0.5 m/s and lands in the field (a free orifice gives
    // 3 m/s): an artery spurts with the beat, a vein at 10 mmHg oozes at 0.14 m/s.
    constexpr double kJet_m_s = 0.5;
    constexpr double kJetHead_m2_s2 = 120.0 * sim::kPascalPerMmHg / 1060.0;
    const double pressure_Pa = diastolic_Pa_[b] + pulse_pressure_Pa_[b] * beat;
    const double speed = std::min(
        kJet_m_s * std::sqrt(std::max(pressure_Pa, 0.0) / density / kJetHead_m2_s2), kJet_m_s);
    const double flow = o.area_m2 * speed;
    blood_flow_m3_s_ += flow;
    if (used == emissions_.size()) emissions_.emplace_back();
    BloodEmission& e = emissions_[used++];
    e.sources.assign(o.sources.begin(), o.sources.end());
    e.flow_m3_s = flow;
    e.speed_m_s = speed;
  }
  blood_worker_->queue(blood_due_s_, std::span(emissions_).first(used), world_);
  blood_due_s_ = 0.0;
}

const sim::Blood& SessionSim::blood() const {
  return blood_worker_ ? blood_worker_->settled() : no_blood_;
}

void SessionSim::newest_blood_mm(std::vector<glm::dvec3>& out) const {
  if (blood_worker_) {
    blood_worker_->newest_positions_mm(out);
  } else {
    out.clear();
  }
}

const std::vector<double>& SessionSim::blood_step_ms() const {
  static const std::vector<double> none;
  if (!blood_worker_) return none;
  (void)blood_worker_->settled();
  return blood_worker_->step_ms();
}

void SessionSim::stall_blood_when(std::atomic<bool>* flag, std::chrono::milliseconds how_long) {
  if (blood_worker_) blood_worker_->stall_when(flag, how_long);
}

std::uint64_t SessionSim::blood_behind() const noexcept {
  return blood_worker_ ? blood_worker_->behind() : 0;
}

SessionSim::BloodLag SessionSim::blood_lag() const {
  if (!blood_worker_) return {};
  return {blood_worker_->most_behind(), blood_worker_->tissue_waits(),
          blood_worker_->tissue_waited_ms()};
}

std::uint64_t SessionSim::blood_most_particles() const {
  if (!blood_worker_) return 0;
  (void)blood_worker_->settled();
  return blood_worker_->most_particles();
}

std::size_t SessionSim::close_jaws(Hand& hand, const glm::dvec3& tip_m) {
  const std::int32_t b = nearest_body(tip_m);
  if (b < 0) return 0;
  const glm::dquat& q = hand.orientation;
  const glm::dvec3 half = q * glm::dvec3(options_.jaw_length_mm * 0.5, 0.0, 0.0);
  const glm::dvec3 gap = q * glm::dvec3(0.0, 0.0, jaw_radius_mm_);
  const double r = jaw_radius_mm_ * sim::kMetresPerMillimetre;
  sim::Grasper g{
      {sim::scene_to_sim(hand.tip_mm - half + gap), sim::scene_to_sim(hand.tip_mm + half + gap), r},
      {sim::scene_to_sim(hand.tip_mm - half - gap), sim::scene_to_sim(hand.tip_mm + half - gap),
       r}};
  const std::size_t held = hand.grasp.close(world_.body(static_cast<std::uint32_t>(b)), g,
                                            options_.grasp_capture_mm * sim::kMetresPerMillimetre);
  hand.grasp_body = held > 0 ? b : -1;
  return held;
}

void SessionSim::update_grasp(std::size_t i, const devices::HapticState& state,
                              const glm::dvec3& tip_m) {
  // Grasper: the hand closes and opens it (with hysteresis), or a grasp button held.
  Hand& hand = hands_[i];
  double grip = 0.0;
  for (double a : state.finger_joint_angles_rad)
    grip += a;
  if (!state.finger_joint_angles_rad.empty())
    grip /= static_cast<double>(state.finger_joint_angles_rad.size());
  const bool grip_button = (state.buttons & hand.grasp_buttons) != 0;
  if (!hand.hand_closed && (grip > options_.grasp_close_rad || grip_button)) {
    hand.hand_closed = true;
    if (nearest_body(tip_m) >= 0) {
      const std::size_t held = close_jaws(hand, tip_m);
      add_event(SessionEventKind::GraspClosed, i, hand.grasp_body,
                std::to_string(held) + " vertices held");
    }
  } else if (hand.hand_closed && grip < options_.grasp_open_rad && !grip_button) {
    hand.hand_closed = false;
    if (hand.grasp_body >= 0) {
      hand.grasp.release(world_.body(static_cast<std::uint32_t>(hand.grasp_body)));
      add_event(SessionEventKind::GraspReleased, i, hand.grasp_body, "");
      hand.grasp_body = -1;
    }
  }
  if (hand.grasp_body >= 0)
    hand.grasp.drag(world_.body(static_cast<std::uint32_t>(hand.grasp_body)), tip_m);
}

void SessionSim::update_scalpel(std::size_t i, const devices::HapticState& state,
                                const glm::dvec3& tip_m) {
  Hand& hand = hands_[i];
  const bool button = (state.buttons & hand.cut_buttons) != 0;
  if (button && !hand.button) {
    hand.cut_body = nearest_body(tip_m);
    hand.cut_points_m.assign(world_.body_count(), {});
    hand.cut_tips_m.assign(world_.body_count(), {});
    add_event(SessionEventKind::CutStarted, i, hand.cut_body, "");
  }
  if (button && hand.cut_body >= 0) {
    // Every body the blade crosses is cut: a blade through an organ's face and the vessel lying
    // on it opens both.
    for (std::uint32_t b = 0; b < world_.body_count(); ++b) {
      if (world_.body(b).frozen()) continue;
      sim::ScalpelSweep sweep;
      if (sweep.sample(world_.body(b), world_.bvh(b), tip_m, sim::scene_to_sim(hand.blade_to_mm))) {
        hand.cut_points_m[b].push_back(sweep.points().back());
        hand.cut_tips_m[b].push_back(tip_m);
      }
    }
  }
  if (!button && hand.button && hand.cut_body >= 0) {
    // The body the sweep began on first (its Cut event says why when it was not cut), then the
    // others the blade went through.
    cut_along_sweep(i, static_cast<std::uint32_t>(hand.cut_body));
    for (std::uint32_t b = 0; b < world_.body_count(); ++b) {
      if (static_cast<std::int32_t>(b) != hand.cut_body && hand.cut_points_m[b].size() >= 2)
        cut_along_sweep(i, b);
    }
    hand.cut_body = -1;
    hand.withdrawing = true;
  }
  hand.button = button;
}

void SessionSim::cut_along_sweep(std::size_t i, std::uint32_t b) {
  const std::vector<glm::dvec3>& points = hands_[i].cut_points_m[b];
  const auto body = static_cast<std::int32_t>(b);
  std::string detail;
  try {
    // The held vertices may be renumbered by the cut: a hand holding the body lets go and, when
    // it is another hand, takes hold again where its jaws are once the cut is made (the tissue
    // stays under its tension).
    std::vector<std::size_t> regrasp;
    for (std::size_t o = 0; o < hands_.size(); ++o) {
      if (hands_[o].grasp_body != body) continue;
      hands_[o].grasp.release(world_.body(b));
      hands_[o].grasp_body = -1;
      if (o != i) regrasp.push_back(o);
    }
    const sim::CutResult cut = world_.cut(b, points, {}, hands_[i].cut_tips_m[b]);
    detail = "incision through " + std::to_string(cut.path.size()) + " vertices";
    incisions_.push_back({b, points, hands_[i].cut_tips_m[b]});
    out_.topology_changed = true;
    open_vessel(body, points);
    for (const std::size_t o : regrasp) {
      (void)close_jaws(hands_[o], tips_m_[o]);
      world_.set_probe(o, {hands_[o].grasp_body, hands_[o].cut_body < 0 && !hands_[o].withdrawing});
    }
  } catch (const sim::CutError& e) {
    detail = std::string("no cut: ") + e.what();
  }
  add_event(SessionEventKind::Cut, i, body, std::move(detail));
}

void SessionSim::finger_contacts(Hand& hand, HandOutput& out, const glm::dvec3& tip_m,
                                 const std::vector<double>& joints_rad) {
  std::fill(out.finger_contact_N.begin(), out.finger_contact_N.end(), 0.0);
  if (hand.fingers == 0) return;
  const auto tips =
      fingertips_mm(sim::sim_to_scene(tip_m), hand.orientation, probe_length_mm_, joints_rad);
  constexpr double kReach_m = 0.02;  // deeper than any finger presses
  for (std::size_t f = 0; f < std::min(hand.fingers, tips.size()); ++f) {
    const glm::dvec3 p = sim::scene_to_sim(tips[f]);
    FingerTouch& touch = hand.finger_touch[f];
    double depth = 0.0;
    sim::SurfacePoint deepest;
    for (std::size_t b = 0; b < world_.body_count(); ++b) {
      const auto i = static_cast<std::uint32_t>(b);
      const sim::SurfacePoint c = world_.bvh(i).closest_point(world_.body(i), p, kReach_m);
      const double d = c.found ? penetration_depth(c, p) : 0.0;
      if (d > depth) {
        depth = d;
        deepest = c;
      }
    }
    if (depth > 0.0) {
      // A touch begins at the surface: a fingertip first found deep inside got there through
      // an opening or a jump of the hand, and pressing it out at once would kick the finger.
      if (!touch.touching && depth > kFingerEntryDepth_m) depth = 0.0;
      touch.plane_point_m = deepest.point_m;
      touch.plane_normal = deepest.normal;
      touch.depth_m = depth;
      touch.held_steps = 0;
    } else if (touch.touching && touch.held_steps < kFingerHoldSteps) {
      // The closest point turned sideways (a dent's rim, an edge between faces) while the
      // finger still presses: for a few steps it stays on the plane it touched last, no deeper
      // than it was, so its force does not flicker to zero and back from one step to the next.
      depth = std::clamp(glm::dot(touch.plane_point_m - p, touch.plane_normal), 0.0, touch.depth_m);
      ++touch.held_steps;
    }
    // A touch found below the surface (the finger moved on between two steps, or the surface
    // came to it) starts from the depth it was found at, so the force grows with the press
    // from zero rather than jumping in with whatever depth the step's timing gave.
    if (depth > 0.0 && !touch.touching) touch.entry_depth_m = depth;
    touch.touching = depth > 0.0;
    out.finger_contact_N[f] =
        hand.finger_stiffness_N_per_m * std::max(0.0, depth - touch.entry_depth_m);
  }
}

double SessionSim::penetration_depth(const sim::SurfacePoint& closest, const glm::dvec3& p_m) {
  // Inside the tissue when the closest surface point lies out along its outward normal, straight
  // ahead: a closest point off to the side (on an open rim, a cut's edge) says nothing about
  // inside, since the rim's face normal points across the opening.
  const glm::dvec3 to_surface = closest.point_m - p_m;
  const double along = glm::dot(to_surface, closest.normal);
  if (along <= 0.0 || along < kStraightAhead * glm::length(to_surface)) return 0.0;
  return along;
}

double SessionSim::contact_stiffness(const sim::HapticOutput& h) const {
  // Between steps the proxy stays where the step put it while the tip moves on: the coupling
  // spring in series with the touched volume's compliance under the patch, from the step's
  // own matrix (the force the next step gives for the tip's motion); against a membrane (no
  // compliance) the coupling alone.
  if (!h.contact) return coupling_N_per_m_;
  return 1.0 / (1.0 / coupling_N_per_m_ + h.compliance_m_per_N);
}

void SessionSim::command_for(const TickOutput& tick_output, std::size_t hand,
                             const glm::dvec3& tip_now_m, std::vector<double>& command_N,
                             double since_step_s) const {
  const Hand& h = hands_[hand];
  const HandOutput& step = tick_output.hand(hand);
  // In contact the proxy stays where the step put it while the tip moves on: the contact's
  // stiffness times the tip's motion relative to the surface is added (the coupling spring
  // alone against a membrane, which stands still between steps, in series with the tissue's
  // compliance against a volume, which goes on moving). Outside contact there is no force.
  glm::dvec3 force = step.force_N;
  if (step.contact) {
    const glm::dvec3 surface_moved = since_step_s * step.patch_velocity_m_s;
    force += step.contact_stiffness_N_per_m * (step.tip_m + surface_moved - tip_now_m);
  }
  const double contact_N = std::min(glm::length(force), h.setup.max_force_N);
  command_N.resize(h.command_size);
  std::size_t k = 0;
  for (std::size_t i = 0; i < h.setup.channels.size(); ++i) {
    const devices::ForceChannel& c = h.setup.channels[i];
    const devices::ChannelRole& role = h.roles[i];
    const double limit_N = std::min(h.setup.max_force_N, c.max_force_N);
    if (role.use == devices::ChannelUse::Vector) {
      // The force itself, in the device's frame: scaled down as a whole, never turned.
      glm::dvec3 f = h.setup.device_frame.force_to_device(force);
      const double along[3] = {f.x, f.y, f.z};
      const double magnitude = devices::force_extent(c, along);  // per axis when rated so
      if (magnitude > limit_N) f *= limit_N / magnitude;
      command_N[k++] = f.x;
      command_N[k++] = f.y;
      command_N[k++] = f.z;
      continue;
    }
    double f = 0.0;
    if (role.use == devices::ChannelUse::Finger) {
      if (role.finger < step.finger_contact_N.size()) f += step.finger_contact_N[role.finger];
      if (role.finger < 2) f += contact_N;  // thumb and index hold the instrument
      if (step.grasping) f += options_.grasp_force_N;
      f = std::min(f, limit_N);
    } else if (c.unitless && c.components == 1) {
      f = step.cutting ? options_.cut_vibration : 0.0;  // a cue, not a force
    }
    for (std::size_t j = 0; j < c.components; ++j)
      command_N[k++] = j == 0 ? f : 0.0;
  }
}

std::uint64_t SessionSim::state_hash() {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](std::uint64_t v) {
    for (int i = 0; i < 8; ++i) {
      h ^= (v & 0xffu);
      h *= 1099511628211ull;
      v >>= 8;
    }
  };
  for (std::size_t b = 0; b < world_.body_count(); ++b)
    mix(world_.body(static_cast<std::uint32_t>(b)).state_hash());
  // The blood too, once there is any (a session without it keeps its hash).
  for (const glm::dvec3& p : blood().positions()) {
    for (int k = 0; k < 3; ++k) {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &p[k], sizeof bits);
      mix(bits);
    }
  }
  return h;
}

}  // namespace bisturi::runtime
