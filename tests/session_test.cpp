// Session groundwork: scene files and their errors, the embedded default scene, the
// lock-free hand-off between threads, timing summaries and the report's plots.

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <atomic>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <glm/glm.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/fault_injection.h"
#include "bisturi/runtime/session/plots.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/timing.h"
#include "bisturi/runtime/session/triple_buffer.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/units.h"

namespace bisturi::runtime {
namespace {

std::string error_of(const std::string& toml) {
  try {
    (void)parse_scene(toml, "scene.toml");
  } catch (const SceneFileError& e) {
    return e.what();
  }
  return "no error";
}

TEST(SceneFile, DefaultSceneIsTheShippedFileAndParses) {
  std::ifstream in(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), std::string(default_scene_toml()));
  const SceneDescription scene = default_scene();
  EXPECT_EQ(scene.name, "liver");
  ASSERT_EQ(scene.solids.size(), 2u);
  EXPECT_EQ(scene.solids[0].source, SolidDescription::Source::Volume);
  EXPECT_EQ(scene.solids[0].model, SolidDescription::Model::Volume);
  EXPECT_EQ(scene.solids[1].source, SolidDescription::Source::Phantom);
  EXPECT_EQ(scene.solids[1].anchors.size(), 2u);
  ASSERT_EQ(scene.devices.size(), 2u);
  EXPECT_EQ(scene.devices[1].role, DeviceDescription::Role::HeadTracker);
  EXPECT_EQ(scene.devices[0].driver, "hid-glove");
  EXPECT_EQ(scene.devices[1].driver, "hid-tracker");
  ASSERT_EQ(scene.instruments.size(), 3u);
  EXPECT_EQ(scene.instruments[0].device, "glove");
  EXPECT_DOUBLE_EQ(scene.rates.haptic_hz, 1000.0);
}

TEST(SceneFile, LiverSceneIsAShippedFileAndParses) {
  const SceneDescription scene =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  EXPECT_EQ(scene.name, "liver");
  ASSERT_EQ(scene.solids.size(), 2u);
  // The organ: the liver label of the label map beside the file; the vessel: a phantom.
  EXPECT_EQ(scene.solids[0].source, SolidDescription::Source::Volume);
  EXPECT_EQ(scene.solids[0].label, 255u);
  EXPECT_EQ(scene.solids[1].source, SolidDescription::Source::Phantom);
  EXPECT_EQ(scene.solids[1].anchors.size(), 2u);
  ASSERT_TRUE(scene.procedure.has_value());
  ASSERT_EQ(scene.devices.size(), 2u);
  EXPECT_EQ(scene.devices[0].driver, "hid-glove");
  ASSERT_EQ(scene.instruments.size(), 3u);
}

TEST(SceneFile, ErrorsNameTheFileLineAndKey) {
  EXPECT_EQ(error_of("name = 3"), "scene.toml: line 1: key 'name': expected a string");
  EXPECT_EQ(error_of("\n[rates]\nhaptic_hz = -1"),
            "scene.toml: line 3: key 'rates.haptic_hz': must be greater than 0");
  EXPECT_NE(error_of("[[solids]]\nphantom = 'sphere'\nstifness = 3")
                .find("line 3: key 'solids[0].stifness': unknown key"),
            std::string::npos);
  EXPECT_NE(error_of("[[solids]]\nmesh = 'no_such_file.obj'").find("no such file"),
            std::string::npos);
  EXPECT_NE(error_of("x = [").find("scene.toml: line 1:"), std::string::npos);
  EXPECT_EQ(
      error_of("[[devices]]\nname = 'g'\ndriver = 'hid-glove'\n[[instruments]]\ndevice = 'h'"),
      "scene.toml: line 5: key 'instruments[0].device': no device named 'h'");
  EXPECT_NE(error_of("[headset]\nfov_deg = [45, 45, 95, 45]").find("headset.fov_deg[2]"),
            std::string::npos);
  EXPECT_NE(error_of("[[solids]]\nphantom = 'sphere'\nmesh = 'a.obj'").find("exactly one of"),
            std::string::npos);
  EXPECT_NE(error_of("[simulation]\nfar_field_interval = 0")
                .find("line 2: key 'simulation.far_field_interval'"),
            std::string::npos);
  EXPECT_NE(error_of("[simulation]\nfar_field = 8").find("unknown key"), std::string::npos);
}

TEST(SceneFile, TheShippedLiverSceneFileReadsTheLabelMapBesideIt) {
  // As a file on disk the liver scene names config/data/liver.nrrd, not the embedded copy.
  const SceneDescription scene =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  EXPECT_FALSE(scene.solids[0].embedded);
  EXPECT_TRUE(std::filesystem::exists(scene.solids[0].path));
  EXPECT_EQ(scene.solids[0].path.filename(), "liver.nrrd");
  // A scene file without the file beside it (the default scene printed and edited elsewhere)
  // gets the embedded one; other missing files are still errors.
  const SceneDescription elsewhere = parse_scene(
      "[[solids]]\nvolume = 'data/liver.nrrd'\nlabel = 255", "scene.toml", "/nonexistent");
  EXPECT_TRUE(elsewhere.solids[0].embedded);
  EXPECT_NE(error_of("[[solids]]\nvolume = 'data/kidney.nrrd'\nlabel = 1").find("no such file"),
            std::string::npos);
}

TEST(SceneFile, ProcedureTableSetsTheTargets) {
  const SceneDescription scene = parse_scene(
      "[procedure]\npalpate_mm = [1, 2, 3]\npalpate_normal = [0, 0, 2]\ngrasp_mm = [4, 5, 6]\n"
      "cut_from_mm = [0, 0, 0]\ncut_to_mm = [10, 0, 0]\ncut_normal = [0, -3, 0]\n"
      "cut_depth_mm = 12\npull_mm = 4",
      "scene.toml");
  ASSERT_TRUE(scene.procedure.has_value());
  const ProcedureDescription& p = *scene.procedure;
  EXPECT_EQ(p.palpate_mm, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(p.palpate_normal, (std::array<double, 3>{0, 0, 1}));  // normalised
  EXPECT_EQ(p.cut_normal, (std::array<double, 3>{0, -1, 0}));
  EXPECT_EQ(p.grasp_normal, (std::array<double, 3>{0, -1, 0}));  // the default
  EXPECT_DOUBLE_EQ(p.cut_depth_mm, 12.0);
  EXPECT_DOUBLE_EQ(p.pull_mm, 4.0);
  EXPECT_DOUBLE_EQ(p.palpate_depth_mm, 6.0);
  EXPECT_FALSE(parse_scene("name = 'x'", "scene.toml").procedure.has_value());

  const std::string targets =
      "[procedure]\npalpate_mm = [1, 2, 3]\ngrasp_mm = [4, 5, 6]\ncut_from_mm = [0, 0, 0]\n";
  EXPECT_NE(error_of(targets).find("key 'procedure.cut_to_mm': missing"), std::string::npos);
  EXPECT_NE(error_of(targets + "cut_to_mm = [0, 0, 0]").find("two different ends"),
            std::string::npos);
  EXPECT_NE(error_of(targets + "cut_to_mm = [1, 0, 0]\ncut_normal = [0, 0, 0]")
                .find("line 6: key 'procedure.cut_normal': must not be zero"),
            std::string::npos);
  EXPECT_NE(error_of(targets + "cut_to_mm = [1, 0, 0]\ncut_depth_mm = -1")
                .find("key 'procedure.cut_depth_mm'"),
            std::string::npos);
  EXPECT_NE(error_of(targets + "cut_to_mm = [1, 0, 0]\ncut_speed = 3").find("unknown key"),
            std::string::npos);
  EXPECT_NE(error_of("[[solids]]\nphantom = 'sphere'\ndownsample = [2, 2, 2]")
                .find("only for a label map"),
            std::string::npos);
}

TEST(SceneFile, TheSweepIsOnUnlessTheSimulationTableTurnsItOff) {
  EXPECT_TRUE(default_scene().simulation.continuous_collision);
  EXPECT_FALSE(parse_scene("[simulation]\ncontinuous_collision = false", "scene.toml")
                   .simulation.continuous_collision);
  EXPECT_THROW((void)parse_scene("[simulation]\ncontinuous_collision = 1", "scene.toml"),
               std::exception);
}

TEST(SceneFile, SimulationTableSetsMultirateStepping) {
  EXPECT_EQ(default_scene().simulation.far_field_interval, 1);
  const SceneDescription large =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/large_organ.toml");
  EXPECT_EQ(large.name, "large-organ");
  EXPECT_EQ(large.simulation.far_field_interval, 32);
  EXPECT_EQ(parse_scene("[simulation]\nfar_field_interval = 32", "scene.toml")
                .simulation.far_field_interval,
            32);
}

TEST(SceneFile, RelativeMeshPathsResolveAgainstTheSceneFolder) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("bisturi_scene_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "organ.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(dir / "scene.toml") << "name = 'file'\n[[solids]]\nmesh = 'organ.obj'\n";
  const SceneDescription scene = read_scene_file(dir / "scene.toml");
  ASSERT_EQ(scene.solids.size(), 1u);
  EXPECT_EQ(scene.solids[0].path, dir / "organ.obj");
  EXPECT_EQ(scene.file, dir / "scene.toml");
  std::filesystem::remove_all(dir);
}

TEST(TripleBuffer, ConsumerSeesOnlyWholeValuesAndTheNewest) {
  struct Pair {
    std::uint64_t a = 0, b = 0;
  };
  TripleBuffer<Pair> buffer;
  EXPECT_FALSE(buffer.take());
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (std::uint64_t i = 1; i <= 200000; ++i) {
      buffer.back() = Pair{i, i * 3};
      buffer.publish();
    }
    done = true;
  });
  std::uint64_t last = 0;
  std::size_t torn = 0, backwards = 0;
  while (!done.load() || buffer.take()) {
    if (buffer.take()) {
      const Pair& p = buffer.front();
      torn += p.b != p.a * 3 ? 1 : 0;
      backwards += p.a < last ? 1 : 0;
      last = p.a;
    }
  }
  producer.join();
  buffer.take();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(buffer.front().a, 200000u);  // the newest value always arrives
}

TEST(Timing, SummaryPercentilesAndThinning) {
  TimingRecorder recorder("ms", 1000);
  for (int i = 1; i <= 100; ++i)
    recorder.record(i);
  TimingSummary s = recorder.summary();
  EXPECT_EQ(s.count, 100u);
  EXPECT_DOUBLE_EQ(s.p50, 50.5);
  EXPECT_NEAR(s.p99, 99.01, 1e-9);
  EXPECT_DOUBLE_EQ(s.max, 100.0);
  EXPECT_DOUBLE_EQ(s.mean, 50.5);
  TimingRecorder small("us", 64);
  for (int i = 0; i < 10000; ++i)
    small.record(i % 100);
  EXPECT_LE(small.samples().size(), 64u);
  EXPECT_EQ(small.summary().count, 10000u);
  EXPECT_NEAR(small.summary().p50, 50.0, 10.0);  // uniform thinning keeps the distribution
  EXPECT_DOUBLE_EQ(small.summary().max, 99.0);
}

// A full recorder thins a few samples per record: whenever it is read, mid-thinning or not, it
// holds an evenly spaced subset of what came, in order, within its capacity.
TEST(Timing, ThinningAFewSamplesPerRecordKeepsAnEvenSubsetInOrder) {
  constexpr std::size_t kCapacity = 4096;
  for (const std::size_t count : {kCapacity, kCapacity + 1, kCapacity + 7, 3 * kCapacity + 5,
                                  10 * kCapacity, 37 * kCapacity + 11}) {
    TimingRecorder ramp("us", kCapacity);
    for (std::size_t i = 0; i < count; ++i)
      ramp.record(static_cast<double>(i));
    const std::vector<double>& kept = ramp.samples();
    ASSERT_LE(kept.size(), kCapacity) << count;
    ASSERT_GE(kept.size(), kCapacity / 2) << count;
    EXPECT_EQ(kept.front(), 0.0) << count;
    const double spacing = kept[1] - kept[0];
    for (std::size_t k = 1; k < kept.size(); ++k)
      ASSERT_EQ(kept[k] - kept[k - 1], spacing) << count << " samples, at " << k;
    EXPECT_GT(kept.back() + spacing, static_cast<double>(count - 1)) << "the newest are kept";
    EXPECT_EQ(ramp.summary().count, count);
    EXPECT_NEAR(ramp.summary().p50, 0.5 * static_cast<double>(count), spacing) << count;
  }
}

TEST(Plots, HistogramAndSeriesArePngFiles) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("bisturi_plots_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::vector<double> samples;
  for (int i = 0; i < 1000; ++i)
    samples.push_back(1.0 + 0.01 * std::sin(i));
  write_histogram_png(dir / "h.png", "haptic period", "ms", samples);
  std::vector<double> t{0, 1, 2, 3};
  std::vector<Series> series{{"force", {0, 1, 2, 1}}};
  write_series_png(dir / "s.png", "force", "s", "N", t, series, 2.5);
  for (const char* name : {"h.png", "s.png"}) {
    std::ifstream in(dir / name, std::ios::binary);
    char magic[8] = {};
    in.read(magic, 8);
    EXPECT_EQ(std::string(magic + 1, 3), "PNG") << name;
    EXPECT_GT(std::filesystem::file_size(dir / name), 1000u) << name;
  }
  EXPECT_THROW(write_histogram_png(dir / "missing_dir" / "h.png", "x", "ms", samples),
               std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bisturi::runtime

namespace bisturi::runtime {
namespace {

glm::dvec3 mm_of(const devices::Pose& pose) {
  return sim::sim_to_scene({pose.position_m.x, pose.position_m.y, pose.position_m.z});
}

// The liver scene's organ is the liver of the label map, small enough for the tissue step, closed
// and of genus 0; its procedure goes where the scene file says, and the cut sweeps across the
// vessel.
TEST(LiverScene, TheLiverIsBuiltAndTheProcedureFollowsTheScene) {
  const SceneDescription scene =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  const std::vector<BuiltSolid> solids = build_solids(scene);
  ASSERT_EQ(solids.size(), 2u);
  const Dlfl& liver = solids[0].mesh;
  EXPECT_TRUE(validate(liver).ok());
  const MeshStatistics stats = mesh_statistics(liver);
  ASSERT_EQ(stats.parts.size(), 1u);
  EXPECT_EQ(stats.parts[0].rings, 0u);
  EXPECT_EQ(stats.parts[0].genus, 0);
  EXPECT_GT(liver.num_vertices(), 600u);
  EXPECT_LT(liver.num_vertices(), 1000u);
  // A liver-sized organ: about 20 x 17 x 15 cm.
  glm::dvec3 lo(1e9), hi(-1e9);
  for (std::size_t v = 0; v < liver.vertex_capacity(); ++v) {
    lo = glm::min(lo, liver.positions()[v]);
    hi = glm::max(hi, liver.positions()[v]);
  }
  EXPECT_NEAR(hi.x - lo.x, 204.0, 10.0);
  EXPECT_NEAR(hi.z - lo.z, 150.0, 10.0);

  const auto duration = devices::Nanoseconds(10'000'000'000);
  const Procedure p = make_procedure("default", solids, duration, devices::SimulatedGlove::kJoints);
  const ProcedureDescription& d = *scene.procedure;
  const glm::dvec3 start = mm_of(p.first_hand.pose_at(devices::Nanoseconds(0)));
  const glm::dvec3 palpate(d.palpate_mm[0], d.palpate_mm[1], d.palpate_mm[2]);
  const glm::dvec3 pn(d.palpate_normal[0], d.palpate_normal[1], d.palpate_normal[2]);
  EXPECT_LT(glm::length(start - (palpate + 30.0 * pn)), 1e-6);
  // The palpation target lies on the built liver (within a few millimetres of a vertex).
  double nearest = 1e9;
  for (std::size_t v = 0; v < liver.vertex_capacity(); ++v)
    nearest = std::min(nearest, glm::length(liver.positions()[v] - palpate));
  EXPECT_LT(nearest, 12.0);

  // During the cut the blade (the scalpel's length from the tip along the cut's normal) passes
  // from one side of the vessel to the other and through its extent.
  double blade_mm = 0.0;
  for (const InstrumentDescription& in : scene.instruments)
    if (in.kind == InstrumentDescription::Kind::Scalpel) blade_mm = in.length_mm;
  ASSERT_GT(blade_mm, 0.0);
  glm::dvec3 vlo(1e9), vhi(-1e9);
  for (std::size_t v = 0; v < solids[1].mesh.vertex_capacity(); ++v) {
    vlo = glm::min(vlo, solids[1].mesh.positions()[v]);
    vhi = glm::max(vhi, solids[1].mesh.positions()[v]);
  }
  const glm::dvec3 cn(d.cut_normal[0], d.cut_normal[1], d.cut_normal[2]);
  const ProcedurePhase* cut = nullptr;
  for (const ProcedurePhase& phase : p.phases)
    if (phase.name == "cut") cut = &phase;
  ASSERT_NE(cut, nullptr);
  bool left = false, right = false, through = false;
  for (auto t = cut->begin; t <= cut->end; t += devices::Nanoseconds(5'000'000)) {
    if (p.first_hand.buttons_at(t) == 0) continue;  // the blade is live while the button is held
    const glm::dvec3 tip = mm_of(p.first_hand.pose_at(t));
    left = left || tip.x < vlo.x;
    right = right || tip.x > vhi.x;
    for (double along = 0.0; along <= blade_mm; along += 0.5) {
      const glm::dvec3 b = tip + along * cn;
      through = through || (b.x > vlo.x && b.x < vhi.x && b.y > vlo.y && b.y < vhi.y &&
                            b.z > vlo.z && b.z < vhi.z);
    }
  }
  EXPECT_TRUE(left);
  EXPECT_TRUE(right);
  EXPECT_TRUE(through);
}

TEST(FaultInjection, ParsesAFaultAndItsTimeAndRefusesTheRest) {
  const InjectedFault f = parse_fault("tissue-hang@2.5");
  EXPECT_EQ(f.kind, FaultKind::TissueHang);
  EXPECT_DOUBLE_EQ(f.at_s, 2.5);
  EXPECT_EQ(parse_fault("trace-slow-disk@0").kind, FaultKind::TraceSlowDisk);
  EXPECT_EQ(parse_fault("blood-stall@1").kind, FaultKind::BloodStall);
  for (const char* bad :
       {"tissue-hang", "tissue-hang@", "tissue-hang@-1", "tissue-hang@2s", "melt@1", "@1"}) {
    try {
      (void)parse_fault(bad);
      ADD_FAILURE() << bad << " was taken";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(bad), std::string::npos) << what;
      EXPECT_NE(what.find("device-unplug"), std::string::npos) << "names the faults: " << what;
    }
  }
}

}  // namespace
}  // namespace bisturi::runtime
