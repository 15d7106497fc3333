#pragma once
// The simulation side of one haptic tick, shared by the live session and its replay so both run
// exactly the same code on the same inputs: haptic state in -> instruments (probe, grasper,
// scalpel) -> SimWorld step (collision, proxy force, soft tissue) -> the force command for the
// haptic device's channels. Nothing here reads a clock: the step length is the scene's fixed haptic
// period, so a replay in virtual time reaches bit-identical forces and state.
//
// How a haptic device drives the instruments (device poses are SI metres in the scene's world
// frame, so the one unit seam is sim::scene_to_sim / sim_to_scene):
//  - the end effector's position is the probe tip (the haptic point of the god-object proxy);
//  - closing the hand (mean finger joint angle above grasp_close_rad) closes the grasper's jaws
//    at the tip, opening it (below grasp_open_rad) releases;
//  - button 0 held sweeps the scalpel blade (from the tip along the hand's +z, blade_length) and
//    its release cuts along the sweep.

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"
#include "bisturi/runtime/session/device_frame.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/sim/blood.h"
#include "bisturi/sim/grasp.h"
#include "bisturi/sim/world.h"

namespace bisturi::runtime {

class BloodWorker;
struct BloodEmission;

/// Something a device did that the picture must show (action-to-response is measured from it).
enum class SessionEventKind : std::uint8_t { Contact, GraspClosed, GraspReleased, CutStarted, Cut };
const char* to_string(SessionEventKind kind);

struct SessionEvent {
  SessionEventKind kind = SessionEventKind::Contact;
  std::uint64_t tick = 0;
  std::int32_t body = -1;
  std::uint32_t hand = 0;  ///< the hand (haptic device) whose instrument did it
  std::string detail;      ///< e.g. "42 vertices held", "path of 9 vertices", the cut error
};

/// A step of a solid that diverged (sim::SimEvent: rolled back and retried in substeps, or
/// frozen), at the session tick its step started on (as SessionEvent's).
struct Divergence {
  std::uint64_t tick = 0;
  sim::SimEvent event;
};

/// A cut that was made: the body and where the blade crossed its surface (metres), as
/// sim::cut_surface took them. A drawn surface finer than the simulated one is cut along the same
/// points (drawn_surface.h).
struct Incision {
  std::uint32_t body = 0;
  std::vector<glm::dvec3> points_m;
  /// Where the blade's tip was at each point: a solid's wound has walls down to it.
  std::vector<glm::dvec3> tips_m;
};

/// One hand's share of a step: its instrument's force and what its device is commanded.
struct HandOutput {
  glm::dvec3 force_N{0.0};        ///< proxy force on the tip (world frame)
  glm::dvec3 tip_m{0.0};          ///< the tip the step was computed for
  std::vector<double> command_N;  ///< per force component of the hand's device, before its guard
  /// Per finger actuator (the device's 1-component channels with a force unit, in order): the
  /// force of that finger's own contact with the tissue (N, >= 0; hand_model.h).
  std::vector<double> finger_contact_N;
  bool contact = false;
  /// How the contact force grows per metre the tip moves on into the tissue before the next
  /// step (N/m): what command_for adds for the tip's motion since this step.
  double contact_stiffness_N_per_m = 0.0;
  /// How the touched surface goes on moving after the step (m/s, along its normal; zero on a
  /// membrane): command_for counts its motion since the step as the tip's, the other way.
  glm::dvec3 patch_velocity_m_s{0.0};
  bool grasping = false;  ///< the grasper holds tissue after this step
  bool cutting = false;   ///< the scalpel is sweeping after this step
};

/// A step's output. The first hand's is the TickOutput itself (all a one-handed session has);
/// the others' are in other_hands: hand(i) reads either.
struct TickOutput : HandOutput {
  std::vector<HandOutput> other_hands;
  bool topology_changed = false;
  std::size_t events = 0;  ///< events added by this tick (the last ones of events())
  [[nodiscard]] const HandOutput& hand(std::size_t i) const {
    return i == 0 ? *this : other_hands[i - 1];
  }
  HandOutput& hand(std::size_t i) { return i == 0 ? *this : other_hands[i - 1]; }
};

/// Most threads a tissue step may use (the integrator's team limit).
constexpr std::uint32_t kMaxTissueThreads = 64;

struct SessionSimOptions {
  double grasp_close_rad = 0.7;
  double grasp_open_rad = 0.4;
  double grasp_capture_mm = 1.0;
  double jaw_length_mm = 8.0;
  double blade_length_mm = 15.0;
  /// Glove actuator force while the grasper holds tissue (the fingers feel the jaws close).
  double grasp_force_N = 0.8;
  /// Haptics intensity (0-1) while the scalpel cuts.
  double cut_vibration = 0.3;
  /// Threads of the soft-tissue step (sim::IntegratorOptions::threads). The bits of the state
  /// depend on it, so a trace records it and its replay uses the same count.
  unsigned tissue_threads = 1;
  /// The first hand's device (a session with more hands gives each a HandSetup):
  /// Where the haptic device sits in the scene: its poses arrive in the scene frame (the haptic
  /// loop converts them), and a 3-component channel's force vector leaves through the inverse
  /// rotation, in the device's own frame.
  DeviceFrame device_frame;
  /// The device's datasheet limits: the coupling spring and the fingers' contact stiffness never
  /// exceed max_stiffness_N_per_m (when it is given).
  devices::DeviceSpec device_spec;
  /// Stiffness of a fingertip's own contact with the tissue (before the device's limit).
  double finger_stiffness_N_per_m = 300.0;
  /// What each force channel gets (the driver's ChannelLayout, devices/registry.h); empty: by
  /// the channel's shape (3 components a vector, 1 with a force unit the next finger).
  std::vector<devices::ChannelRole> channel_roles;
  /// What each button does (the driver's ChannelLayout::buttons, by bit); empty: button 0 cuts.
  /// A Grasp button closes the grasper as a glove's closing fingers do.
  std::vector<devices::ButtonUse> button_uses;
};

/// One hand: a haptic device and the instruments it drives (SessionSimOptions' per-device
/// fields, for each device).
struct HandSetup {
  std::vector<devices::ForceChannel> channels;
  DeviceFrame device_frame;
  devices::DeviceSpec device_spec;
  std::vector<devices::ChannelRole> channel_roles;
  std::vector<devices::ButtonUse> button_uses;
  double max_force_N = 3.0;  ///< the scene's limit for the device
};

class SessionSim {
 public:
  /// Takes the built solids (moved into soft bodies) and the haptic device's force channel layout:
  /// one hand, its device the options' (its limit the scene's first haptic device's max_force_N).
  ~SessionSim();
  SessionSim(SessionSim&&) noexcept;
  SessionSim& operator=(SessionSim&&) noexcept;
  SessionSim(const SceneDescription& scene, std::vector<BuiltSolid> solids,
             std::vector<devices::ForceChannel> channels, const SessionSimOptions& options = {});
  /// One hand per setup (at least one), acting on the same tissue in the same steps.
  SessionSim(const SceneDescription& scene, std::vector<BuiltSolid> solids,
             std::vector<HandSetup> hands, const SessionSimOptions& options = {});

  /// One simulation step with the haptic device in `state`, covering `ticks` haptic periods (its
  /// time step; the tissue may step at a fraction of the haptic rate, see step_schedule.h).
  /// `blood_held`: the blood's clock stands still over this step (its thread is behind; the
  /// session notes when in its trace, so a replay holds the same steps).
  const TickOutput& tick(const devices::HapticState& state, std::uint32_t ticks = 1,
                         bool blood_held = false);
  /// The same with hand i's device in states[i] (one state per hand).
  const TickOutput& tick(std::span<const devices::HapticState> states, std::uint32_t ticks = 1,
                         bool blood_held = false);
  [[nodiscard]] double haptic_period_ms() const { return 1000.0 / haptic_hz_; }
  [[nodiscard]] std::size_t hand_count() const { return hands_.size(); }

  /// The device's command for a step's output with the tip now at tip_now_m (scene frame; the
  /// step may be a few ticks old when the tissue runs on its own thread, `since_step_s` after
  /// the state it ran on): the proxy force corrected for the tip's motion since the step
  /// relative to the touched surface (which goes on at its velocity), by the coupling spring in
  /// series with the tissue's compliance, so the force follows the hand at the haptic rate.
  /// By channel role: a Vector channel gets that force in the
  /// device's frame (its magnitude capped, its direction kept); a Finger channel that finger's
  /// own contact, plus the instrument's reaction for the thumb and index that hold it, plus the
  /// grasp while the jaws hold tissue; an Unused channel zero, except a unitless one (a
  /// vibration motor), which vibrates while the scalpel cuts.
  /// For the step's own tip it is the step's command_N, bit for bit. Reads only what the
  /// constructor set: safe to call from another thread while tick() runs.
  void command_for(const TickOutput& step, const glm::dvec3& tip_now_m,
                   std::vector<double>& command_N) const {
    command_for(step, 0, tip_now_m, command_N);
  }
  /// command_for for hand `hand`'s device.
  void command_for(const TickOutput& step, std::size_t hand, const glm::dvec3& tip_now_m,
                   std::vector<double>& command_N, double since_step_s = 0.0) const;
  /// The probe tip (metres) of a haptic state: its first end effector's position.
  static glm::dvec3 tip_of(const devices::HapticState& state);
  /// Number of force components of a hand's command.
  [[nodiscard]] std::size_t command_size(std::size_t hand = 0) const {
    return hands_[hand].command_size;
  }
  /// A hand's force channels as the session limits them (each no stronger than the scene's
  /// max_force_N): what the force guard checks, so a command at the scene's limit counts as
  /// clamped there.
  [[nodiscard]] std::vector<devices::ForceChannel> guard_channels(std::size_t hand = 0) const;

  [[nodiscard]] std::size_t body_count() const { return world_.body_count(); }
  sim::SimWorld& world() { return world_; }
  [[nodiscard]] const std::string& body_name(std::size_t i) const { return names_[i]; }
  /// Haptic ticks simulated so far (the sum of the steps' ticks).
  [[nodiscard]] std::uint64_t ticks() const { return ticks_; }
  [[nodiscard]] const std::vector<SessionEvent>& events() const { return events_; }
  /// The cuts made so far, in order.
  [[nodiscard]] const std::vector<Incision>& incisions() const { return incisions_; }
  /// Divergence events of the integrator (rollbacks, frozen bodies) so far.
  [[nodiscard]] std::uint64_t divergence_events() const { return divergence_events_; }
  /// The first kKeptDivergences of them, with why each step failed.
  [[nodiscard]] const std::vector<Divergence>& divergences() const { return divergences_; }
  static constexpr std::size_t kKeptDivergences = 64;
  /// Combined state hash of every body (FNV-1a over their SoftBody::state_hash in order).
  [[nodiscard]] std::uint64_t state_hash();
  /// Bleeding: blood leaves a pulsing vessel where a cut opened it, at a flow its lumen pressure
  /// drives through the opening (none while a grasper holds that vessel: clamped), and runs on
  /// the tissue (sim/blood.h), a step every kBloodStep_s of simulated time, on a thread of its
  /// own (runtime/src/session/blood_worker.h). Waits for the steps queued so far: not on the
  /// tissue thread during a session (newest_blood_mm is for that).
  [[nodiscard]] const sim::Blood& blood() const;
  /// The particles after the newest blood step done (mm; never waits).
  void newest_blood_mm(std::vector<glm::dvec3>& out) const;
  /// Wall time of each blood step so far (ms, on the blood's thread); waits as blood() does.
  [[nodiscard]] const std::vector<double>& blood_step_ms() const;
  /// The most particles the field held at once; waits as blood() does.
  [[nodiscard]] std::uint64_t blood_most_particles() const;
  /// How far the blood's thread fell behind: the most steps queued and not done, and how often
  /// and how long (ms) the tissue thread waited for it (BloodWorker::kMostQueued behind).
  struct BloodLag {
    std::uint64_t most_behind_steps = 0, tissue_waits = 0;
    double tissue_waited_ms = 0.0;
  };
  [[nodiscard]] BloodLag blood_lag() const;
  /// Blood steps queued and not done now (any thread, lock-free: the haptic thread reads it to
  /// decide when the blood's clock holds).
  [[nodiscard]] std::uint64_t blood_behind() const noexcept;
  /// Once `flag` is set, the blood's thread stops for `how_long` in its next step (an injected
  /// fault, fault_injection.h); nothing without a vessel that can bleed. Before the session's
  /// threads start.
  void stall_blood_when(std::atomic<bool>* flag, std::chrono::milliseconds how_long);
  /// Simulated time the blood's clock stood still while vessels bled (s): its lag on the tissue.
  [[nodiscard]] double blood_held_s() const { return blood_held_s_; }
  /// Threads that step the blood (BloodOptions::threads).
  [[nodiscard]] unsigned blood_threads() const { return blood_options_.threads; }
  /// The bleeding openings' flow at the last blood step (m^3/s).
  [[nodiscard]] double blood_flow_m3_s() const { return blood_flow_m3_s_; }
  /// How long building body b's volume took (ms; 0 for a membrane).
  [[nodiscard]] double volume_build_ms(std::size_t b) const { return volume_build_ms_[b]; }
  static constexpr double kBloodStep_s = 1.0 / 90.0;
  /// The pulsing bodies' pressure above diastole now (Pa, as of the last step; 0 without any).
  [[nodiscard]] double pulse_pressure_Pa() const { return pulse_now_Pa_; }
  /// Where a hand's tip and blade are (mm), for drawing the instruments.
  [[nodiscard]] const glm::dvec3& tip_mm(std::size_t hand = 0) const { return hands_[hand].tip_mm; }
  [[nodiscard]] const glm::dvec3& blade_to_mm(std::size_t hand = 0) const {
    return hands_[hand].blade_to_mm;
  }
  [[nodiscard]] bool grasping(std::size_t hand = 0) const { return hands_[hand].grasp_body >= 0; }
  [[nodiscard]] bool cutting(std::size_t hand = 0) const { return hands_[hand].cut_body >= 0; }

 private:
  /// A fingertip's touch begins no deeper than this (a normal press at 1 m/s over a 4 ms step).
  static constexpr double kFingerEntryDepth_m = 0.004;
  /// cos 60 degrees: how far off the normal the closest point may lie for an inside point.
  static constexpr double kStraightAhead = 0.5;
  /// Steps a touching finger keeps its last plane while the closest point lies sideways.
  static constexpr std::uint32_t kFingerHoldSteps = 8;
  /// A finger's contact at the last step: whether it touched, and the tangent plane it pressed.
  struct FingerTouch {
    bool touching = false;
    glm::dvec3 plane_point_m{0.0};
    glm::dvec3 plane_normal{0.0};
    double depth_m = 0.0;          ///< at the last step the closest point was straight ahead
    double entry_depth_m = 0.0;    ///< where the touch began: the force grows from there
    std::uint32_t held_steps = 0;  ///< steps since then
  };
  /// A hand's device, its instruments and what they hold.
  struct Hand {
    HandSetup setup;
    std::vector<devices::ChannelRole> roles;  ///< one per channel
    std::size_t command_size = 0;
    std::size_t fingers = 0;  ///< finger actuators (1-component channels with a force unit)
    double finger_stiffness_N_per_m = 300.0;
    std::vector<FingerTouch> finger_touch;  ///< one per finger
    std::uint64_t cut_buttons = 1;          ///< the bits of the buttons that cut
    std::uint64_t grasp_buttons = 0;        ///< the bits of the buttons that grasp
    sim::Grasp grasp;
    std::int32_t grasp_body = -1;
    bool hand_closed = false;
    /// Per body: where the blade crossed its surface during this sweep.
    std::vector<std::vector<glm::dvec3>> cut_points_m;
    /// Per body: where the blade's tip was at each of those points (the sheet it swept).
    std::vector<std::vector<glm::dvec3>> cut_tips_m;
    std::int32_t cut_body = -1;  ///< the body the sweep began on; -1: not cutting
    /// After a cut, until the tip is out of the tissue: the blade leaves along its incision and
    /// parts the tissue as it did while cutting.
    bool withdrawing = false;
    bool button = false;
    bool contact = false;
    std::uint64_t last_contact_tick = 0;
    glm::dvec3 tip_mm{0.0};
    glm::dvec3 blade_to_mm{0.0};
    glm::dquat orientation{1.0, 0.0, 0.0, 0.0};
  };

  std::int32_t nearest_body(const glm::dvec3& p_m);
  /// The contact stiffness of a step's haptic output (TickOutput::contact_stiffness_N_per_m).
  [[nodiscard]] double contact_stiffness(const sim::HapticOutput& h) const;
  void add_event(SessionEventKind kind, std::size_t hand, std::int32_t body, std::string detail);
  /// The hand's grasper closes and opens with its fingers or grasp button; its held tissue
  /// follows the tip.
  void update_grasp(std::size_t hand, const devices::HapticState& state, const glm::dvec3& tip_m);
  /// Closes hand's jaws at its tip on the body nearest it; the vertices held.
  std::size_t close_jaws(Hand& hand, const glm::dvec3& tip_m);
  /// The hand's scalpel: a cut button held sweeps the blade, its release cuts.
  void update_scalpel(std::size_t hand, const devices::HapticState& state, const glm::dvec3& tip_m);
  /// Cuts body b along the hand's sweep (a Cut event either way); hands holding it let go, and
  /// another hand takes hold again where its jaws are.
  void cut_along_sweep(std::size_t hand, std::uint32_t b);
  void finger_contacts(Hand& hand, HandOutput& out, const glm::dvec3& tip_m,
                       const std::vector<double>& joints_rad);
  /// How deep p lies inside the tissue behind its closest surface point (0: outside, or the
  /// closest point is not straight ahead along its normal).
  static double penetration_depth(const sim::SurfacePoint& closest, const glm::dvec3& p_m);

  std::vector<double> volume_build_ms_;  ///< per body
  /// Per body: its pulse pressure (systolic less diastolic, Pa; 0: it does not pulse).
  std::vector<double> pulse_pressure_Pa_;
  double heart_rate_hz_ = 1.2;
  /// Per body: its anchors' displacement at full inspiration (m; zero: it does not breathe).
  std::vector<glm::dvec3> breathing_m_;
  double breathing_period_s_ = 4.0;
  double pulse_now_Pa_ = 0.0;
  /// An opening of a cut vessel: where blood leaves it.
  struct Opening {
    std::int32_t body = -1;
    std::vector<sim::BloodSource> sources;
    double area_m2 = 0.0;
  };
  std::vector<Opening> openings_;
  std::vector<double> diastolic_Pa_;  ///< per body
  sim::BloodOptions blood_options_;
  sim::Blood no_blood_;  ///< what blood() gives before the first opening
  /// Made with the session when a body has a lumen pressure (a vessel that can bleed), so that
  /// other threads may read it while the tissue thread runs; its thread starts at the first
  /// opening.
  std::unique_ptr<BloodWorker> blood_worker_;
  double blood_held_s_ = 0.0;
  std::vector<BloodEmission> emissions_;  ///< scratch: the openings' this blood step
  double blood_due_s_ = 0.0;              ///< simulated time since the last blood step
  double blood_flow_m3_s_ = 0.0;
  /// A cut through body b along `points_m`: an opening when b pulses.
  void open_vessel(std::int32_t body, const std::vector<glm::dvec3>& points_m);
  /// Emits at each opening's flow and steps the blood when kBloodStep_s has passed.
  void bleed(std::uint32_t ticks, bool held);
  /// The pulsing bodies' lumen pressure at the step beginning at ticks_ (sim/pulse.h), and the
  /// breathing bodies' supports moving to where the step covering `ticks` ends.
  void apply_physiology(std::uint32_t ticks);
  SessionSimOptions options_;
  sim::SimWorld world_;
  std::vector<std::string> names_;
  std::vector<Hand> hands_;
  double coupling_N_per_m_ = 0.0;
  double probe_length_mm_ = 60.0;
  double jaw_radius_mm_ = 1.5;
  std::uint64_t ticks_ = 0;
  double haptic_hz_ = 1000.0;
  std::uint32_t step_ticks_ = 1;  ///< ticks the integrator's time step now covers
  std::uint64_t divergence_events_ = 0;
  std::vector<Divergence> divergences_;
  std::vector<SessionEvent> events_;
  std::vector<Incision> incisions_;
  TickOutput out_;
  std::vector<glm::dvec3> tips_m_;             ///< per hand, scratch
  std::vector<sim::HapticOutput> haptic_out_;  ///< per hand, scratch
};

}  // namespace bisturi::runtime
