// Session groundwork (issue 10): scene files and their errors, the embedded default scene, the
// lock-free hand-off between threads, timing summaries and the report's plots.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "bisturi/runtime/session/plots.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/timing.h"
#include "bisturi/runtime/session/triple_buffer.h"

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
  std::ifstream in(std::string(BISTURI_SOURCE_DIR) + "/config/default.toml");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), std::string(default_scene_toml()));
  const SceneDescription scene = default_scene();
  EXPECT_EQ(scene.name, "default");
  ASSERT_EQ(scene.solids.size(), 2u);
  EXPECT_EQ(scene.solids[0].source, SolidDescription::Source::Phantom);
  EXPECT_EQ(scene.solids[1].anchors.size(), 2u);
  ASSERT_EQ(scene.devices.size(), 2u);
  EXPECT_EQ(scene.devices[1].role, DeviceDescription::Role::HeadTracker);
  EXPECT_EQ(scene.devices[0].driver, "hid-glove");
  EXPECT_EQ(scene.devices[1].driver, "hid-tracker");
  ASSERT_EQ(scene.instruments.size(), 3u);
  EXPECT_EQ(scene.instruments[0].device, "glove");
  EXPECT_DOUBLE_EQ(scene.rates.haptic_hz, 1000.0);
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
