#pragma once
// What a session runs: solids, their materials and anchors, instruments, devices, the headset
// and the loop rates. Read from a TOML scene file (config/*.toml, see config/README.md) or taken
// from the embedded default scene. Units are in the names: millimetres for geometry (the scene
// layer's world frame), SI for physics (N/m, N*s/m, kg/m^3), hertz for rates.

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/scene/errors.h"

namespace bisturi::runtime {

/// A scene file that cannot be used: the message names the file, the line and the key.
class SceneFileError : public InputError {
 public:
  using InputError::InputError;
};

/// A solid's material. In physical units: a tissue preset (sim::tissue_presets: liver, kidney,
/// spleen, vessel-wall, fat) and/or Young's modulus, Poisson's ratio, density and retardation
/// time, from which the springs and the volume term are calibrated (sim::calibrate_surface):
/// stiffness_N_per_m, damping_N_s_per_m and bulk_modulus_Pa are then the calibrated ones.
/// stiffness_N_per_m given in the scene is the expert override of the structural spring
/// constant (the scene reader warns that it is one).
struct MaterialDescription {
  std::string preset;               ///< empty: none
  double youngs_modulus_kPa = 0.0;  ///< 0: not given
  double poisson_ratio = 0.45;
  double retardation_time_s = 0.01;
  bool elastic = false;              ///< calibrated from the elastic parameters
  double stiffness_N_per_m = 400.0;  ///< structural spring constant
  double damping_N_s_per_m = 0.8;
  double bulk_modulus_Pa = 2000.0;    ///< the volume term's
  double density_kg_per_m3 = 1050.0;  // soft tissue
  bool stiffness_override = false;    ///< stiffness_N_per_m was given by hand
  std::array<double, 3> colour{0.8, 0.35, 0.3};
};

/// Vertices held in place: those within `distance_mm` of the plane through `point_mm` with
/// normal `normal` on its negative side (e.g. the cut ends of a vessel, an organ's base).
struct AnchorDescription {
  std::array<double, 3> point_mm{0, 0, 0};
  std::array<double, 3> normal{0, 0, 1};
  double distance_mm = 0.0;
};

struct SolidDescription {
  std::string name;
  enum class Source { Mesh, Volume, Phantom } source = Source::Phantom;
  /// Mesh or volume file, resolved against the scene file's folder. In the embedded default
  /// scene: the name of a file embedded in the program (see embedded_data.h), e.g.
  /// "data/liver.nrrd" for config/data/liver.nrrd.
  std::filesystem::path path;
  bool embedded = false;  ///< `path` names an embedded file, not one on disk
  // Phantom volumes (source Phantom): see bisturi/scene/volume/phantoms.h.
  std::string phantom = "sphere";
  std::array<std::int64_t, 3> dims{48, 48, 48};
  double spacing_mm = 1.0;
  double a_mm = 0.0;
  double b_mm = 0.0;
  // Extraction (Volume and Phantom sources).
  double iso = 0.0;
  std::optional<std::uint32_t> label;  ///< extract this label of a label map instead of `iso`
  /// Label maps: blocks of this many samples per axis become one before extraction (a label
  /// where at least half the block is; see downsample_label), for a coarse tissue model.
  std::array<int, 3> downsample{1, 1, 1};
  double decimate = 1.0;  ///< fraction of faces kept
  int smooth = 0;         ///< Taubin iterations
  /// Added to every vertex (mm): places the solid in the scene.
  std::array<double, 3> offset_mm{0, 0, 0};
  MaterialDescription material;
  std::vector<AnchorDescription> anchors;
  bool simulate = true;  ///< false: rigid, drawn and touched but not deformed
  /// How the tissue moves: a spring membrane on its surface, or a hexahedral volume under it
  /// (sim/volume/volume_body.h) with cells of cell_mm, elastic from the material's modulus.
  /// Without `model` in the file: a volume when the material gives a modulus and the solid is
  /// simulated (model_given false), and then a membrane after all if its surface turns out open.
  enum class Model { Surface, Volume } model = Model::Surface;
  bool model_given = false;
  double cell_mm = 8.0;
  /// Where the volume's cells are split finer (sim/volume/volume_body.h): the cells meeting the
  /// cube of half_width_mm about centre_mm (scene frame), each into factor^3.
  struct Refinement {
    std::array<double, 3> centre_mm{0, 0, 0};
    double half_width_mm = 0.0;
    int factor = 2;
    /// The box moves to the first hand's contact on the solid when it presses more than half
    /// the half width from the box's centre.
    bool follow = false;
  };
  std::optional<Refinement> refine;
  /// What is drawn, when finer than what is simulated (model volume only): the same source
  /// built with these settings instead, its vertices riding on the volume (drawn_surface.h).
  struct Drawn {
    std::array<int, 3> downsample{1, 1, 1};  ///< label maps only
    double decimate = 1.0;
    int smooth = 0;
  };
  std::optional<Drawn> drawn;
  /// Structures inside it (model volume only): drawn, not simulated, each riding on its volume
  /// as a drawn surface does, hidden while its surface is closed and seen through its openings
  /// (StereoRenderer::set_enclosed_by). Their source keys and offset as a solid's; their colour
  /// in material.colour.
  std::vector<SolidDescription> inner;
  /// The solid's weight is carried by the tissues around it, as in the scan it came from (an
  /// organ in situ is in equilibrium with them): no gravity on its volume (model volume only).
  bool supported = false;
  /// The tissue's resting tension (Pa; model volume only): what pulls a wound open once a cut
  /// separates the volume. 0: a cut stays closed.
  double tension_Pa = 0.0;
  /// At the first cut through the volume, the cells along the blade's sheet split into
  /// cut_refine^3 before they part, so the wound opens as deep and as long as the blade went
  /// (model volume only; 1: the cells part as they are).
  int cut_refine = 1;
  /// A vessel's lumen pressure over the heartbeat, diastolic and systolic (mmHg): the wall is at
  /// rest at diastole and the pressure above it pushes the wall out (sim/pulse.h). Both equal: a
  /// vein's steady pressure (the scene's pressure_mmHg), which moves no wall. None: no lumen.
  std::optional<std::array<double, 2>> pulse_mmHg;
  /// Breathing: the displacement of its anchored part at full inspiration (mm), reached and left
  /// again over each breathing period; the rest of the solid follows through its volume (model
  /// volume only). None: it does not breathe.
  std::optional<std::array<double, 3>> breathing_mm;
};

struct InstrumentDescription {
  std::string name;
  enum class Kind { Probe, Grasper, Scalpel } kind = Kind::Probe;
  double radius_mm = 1.5;
  double length_mm = 60.0;
  /// The device (by name) whose end-effector or finger pose drives it.
  std::string device;
};

struct DeviceDescription {
  std::string name;
  /// Registered driver name (e.g. "hid-glove"), or empty to pick by vendor/product id.
  std::string driver;
  enum class Role { Haptic, HeadTracker } role = Role::Haptic;
  /// Simulated twin through the virtual transport, driven by `script`; false: real hardware.
  bool simulated = true;
  /// The scripted procedure of a simulated device ("default" = approach, palpate, grasp, cut).
  std::string script = "default";
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;
  /// Upper bound on the force sent (the device's own limit applies too, the lower wins).
  double max_force_N = 3.0;
  /// Where a haptic device sits in the scene: its frame's rotation (degrees about the scene's
  /// x, then y, then z axis) and origin (mm) in scene coordinates. Poses come in through it; a
  /// 3-axis force channel gets the force vector through its inverse.
  std::array<double, 3> device_to_scene_rotation_deg{0.0, 0.0, 0.0};
  std::array<double, 3> device_to_scene_translation_mm{0.0, 0.0, 0.0};
};

struct HeadsetDescription {
  double ipd_mm = 63.0;
  /// Per-eye field of view in degrees: left, right, up, down (asymmetric frusta).
  std::array<double, 4> fov_deg{45.0, 45.0, 45.0, 45.0};
  int eye_width = 1024;
  int eye_height = 1024;
  double refresh_hz = 90.0;
  // An OpenXR headset: the reference space (STAGE where the runtime offers it, else LOCAL) and
  // where the scene sits in it: the world point at the operating field's centre (default: the
  // centre of the solids' bounds at the start) is placed field_distance_m ahead of the space's
  // origin and field_height_m above it (default -0.35 in LOCAL, whose origin is at the eyes;
  // 0.95 in STAGE, whose origin is on the floor: a table's height).
  bool stage_space = false;
  std::optional<std::array<double, 3>> field_centre_mm;
  std::optional<double> field_height_m;
  double field_distance_m = 0.45;
};

struct RateDescription {
  double haptic_hz = 1000.0;
  double display_hz = 90.0;
};

/// How the soft tissue is stepped (every solid of the scene).
struct SimulationDescription {
  /// Multirate stepping (sim::IntegratorOptions::far_field_interval): the region around the
  /// instruments every haptic step, the rest of each organ one step of this many haptic periods,
  /// spread over them. 1: every vertex every step. For organs too large for one full step per
  /// haptic period (a 20k-vertex organ at 1 kHz wants 32); the far field then lags as many
  /// periods behind (docs/sim/integrator.md).
  int far_field_interval = 1;
  /// Haptic ticks a tick may go on rendering from an older tissue step than the due one before
  /// its force fades to zero (a hung or slow tissue thread never holds the hand on a spring to a
  /// frozen surface).
  int stale_margin_ticks = 4;
  /// The probe's path within a tick is swept (sim::HapticOptions::continuous), so a fast
  /// gesture cannot pass through a thin or curved surface (docs/sim/collision.md).
  bool continuous_collision = true;
};

/// Targets of the scripted procedure (approach, palpate, grasp, cut) in scene millimetres, so a
/// new anatomy gets a working demonstration without code. Normals are outward unit vectors of
/// the surface at the target: the instrument comes in along them and presses or cuts against
/// them. Without a [procedure] table they come from the solids' bounds (see procedure.h).
struct ProcedureDescription {
  std::array<double, 3> palpate_mm{0, 0, 0};  ///< a point on the organ's surface the probe presses
  std::array<double, 3> palpate_normal{0, 0, 1};
  double palpate_depth_mm = 6.0;            ///< how far the probe presses in
  std::array<double, 3> grasp_mm{0, 0, 0};  ///< a point on a vessel's wall the grasper takes
  std::array<double, 3> grasp_normal{0, -1, 0};
  double pull_mm = 6.0;                        ///< how far the grasper pulls the wall out
  std::array<double, 3> cut_from_mm{0, 0, 0};  ///< the cut's path along the surface
  std::array<double, 3> cut_to_mm{0, 0, 0};
  std::array<double, 3> cut_normal{0, 0, 1};
  double cut_depth_mm = 9.0;  ///< how deep the blade goes below the path
};

/// The body's own motion: the heartbeat that pulses the vessels with a pulse_mmHg, and the
/// breathing that moves the solids with a breathing_mm.
struct PhysiologyDescription {
  double heart_rate_bpm = 72.0;
  double breathing_period_s = 4.0;
  /// Blood from a cut pulsing vessel (sim/blood.h): its density, its viscosity as the XSPH
  /// velocity smoothing (0-1) at the particles' resolution, and the most particles in the field.
  double blood_density_kg_per_m3 = 1060.0;
  double blood_viscosity = 0.1;
  int blood_max_particles = 2000;
};

struct SceneDescription {
  std::string name = "unnamed";
  /// The file it was read from; empty for the embedded default scene.
  std::filesystem::path file;
  std::vector<SolidDescription> solids;
  std::vector<InstrumentDescription> instruments;
  std::vector<DeviceDescription> devices;
  HeadsetDescription headset;
  RateDescription rates;
  SimulationDescription simulation;
  PhysiologyDescription physiology;
  /// The [procedure] table; empty: targets from the solids' bounds.
  std::optional<ProcedureDescription> procedure;
  /// Session length when the command line does not give one.
  double duration_s = 10.0;
};

/// Reads a TOML scene file; SceneFileError names the file, line and key of the first problem
/// (syntax, unknown key, wrong type, value out of range, missing file, a device named by an
/// instrument that does not exist).
SceneDescription read_scene_file(const std::filesystem::path& file);

/// Parses TOML text; `name_for_errors` starts every message, `base_dir` resolves relative paths.
SceneDescription parse_scene(std::string_view toml_text, const std::string& name_for_errors,
                             const std::filesystem::path& base_dir = {});

/// The embedded default scene (needs no file): a liver built from a CT-derived label map
/// embedded in the program (config/data/liver.nrrd) and a vessel segment from a generated
/// phantom along it, a simulated glove and head tracker following the scripted procedure.
SceneDescription default_scene();

/// The embedded default scene as TOML text (what `bisturi run --print-default-scene` shows and
/// what config/liver.toml holds).
std::string_view default_scene_toml();

}  // namespace bisturi::runtime
