#include "bisturi/runtime/render/png_sink.h"

#include "png_writer.h"

#include <png.h>

#include <cstdio>
#include <iomanip>
#include <memory>
#include <sstream>

#include "bisturi/runtime/render/errors.h"

namespace bisturi::render {

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

std::string numbered(const char* stem, std::uint64_t index, const char* suffix) {
  std::ostringstream name;
  name << stem << std::setw(5) << std::setfill('0') << index << suffix << ".png";
  return name.str();
}

double ms_between(PoseClock::time_point from, PoseClock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

/// The libpng calls. libpng reports errors by longjmp, so this function holds no object with a
/// destructor.
bool write_rows(png_structp png, png_infop info, std::FILE* out, std::uint32_t width,
                std::uint32_t height, png_bytep* rows) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  png_init_io(png, out);
  png_set_compression_level(png, 1);  // frames for checking by eye: fast over small
  // One filter, not libpng's default of trying all five on every row: the encoder shares the
  // cores with the session (it was about a sixth of the machine at 2 x 1024 x 1024).
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

}  // namespace

void write_png(const std::filesystem::path& file, std::uint32_t width, std::uint32_t height,
               const std::uint8_t* rgba, std::size_t row_stride_bytes) {
  std::unique_ptr<std::FILE, FileCloser> out(std::fopen(file.c_str(), "wb"));
  if (!out) throw RenderError(file.string() + ": cannot be opened for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr) {
    png_destroy_write_struct(&png, &info);
    throw RenderError(file.string() + ": libpng could not start");
  }
  std::vector<png_bytep> rows(height);
  for (std::uint32_t y = 0; y < height; ++y) {
    rows[y] = const_cast<png_bytep>(rgba + std::size_t{y} * row_stride_bytes);
  }
  const bool ok = write_rows(png, info, out.get(), width, height, rows.data());
  png_destroy_write_struct(&png, &info);
  if (!ok) throw RenderError(file.string() + ": writing the PNG failed");
  if (std::fflush(out.get()) != 0) throw RenderError(file.string() + ": write failed");
}

PngSink::PngSink(std::filesystem::path directory, const PngSinkOptions& options)
    : directory_(std::move(directory)), options_(options), writer_(std::make_unique<PngWriter>()) {
  std::error_code ec;
  std::filesystem::create_directories(directory_, ec);
  if (ec) throw RenderError(directory_.string() + ": cannot create the folder: " + ec.message());
  if (options_.every == 0) options_.every = 1;
  poses_.open(directory_ / "frames.csv");
  if (!poses_) throw RenderError((directory_ / "frames.csv").string() + ": cannot be written");
  poses_ << "frame,image,position_x_mm,position_y_mm,position_z_mm,orientation_w,orientation_x,"
            "orientation_y,orientation_z,pose_to_submit_ms,motion_to_photon_ms\n";
}

void PngSink::consume(const StereoFrame& frame) {
  std::string image;
  if (frame.index % options_.every == 0 && !frame.pixels.empty()) {
    const std::uint32_t w = frame.eye_width;
    const std::uint32_t h = frame.eye_height;
    if (options_.layout == PngLayout::PerEye) {
      for (int e = 0; e < 2; ++e) {
        const std::string name = numbered("frame_", frame.index, e == 0 ? "_left" : "_right");
        const std::uint8_t* px = frame.eye(e).data();
        writer_->write(directory_ / name, w, h,
                       std::vector<std::uint8_t>(px, px + std::size_t{w} * h * 4));
        image += (e == 0 ? "" : " ") + name;
      }
    } else {
      // Side by side: the left eye on the left. Rows interleave the two layers.
      std::vector<std::uint8_t> joined(std::size_t{w} * 2 * h * 4);
      for (std::uint32_t y = 0; y < h; ++y) {
        for (int e = 0; e < 2; ++e) {
          const std::uint8_t* src = frame.eye(e).data() + std::size_t{y} * w * 4;
          std::copy(src, src + std::size_t{w} * 4,
                    joined.data() + (std::size_t{y} * 2 * w + static_cast<std::size_t>(e) * w) * 4);
        }
      }
      image = numbered("frame_", frame.index, "");
      writer_->write(directory_ / image, 2 * w, h, std::move(joined));
    }
  }
  const double latency = ms_between(frame.pose.sample_time, frame.ready_time);
  latencies_ms_.push_back(latency);
  const HeadPose& p = frame.pose;
  poses_ << frame.index << ',' << image << ',' << p.position_mm.x << ',' << p.position_mm.y << ','
         << p.position_mm.z << ',' << p.orientation.w << ',' << p.orientation.x << ','
         << p.orientation.y << ',' << p.orientation.z << ','
         << ms_between(p.sample_time, frame.submit_time) << ',' << latency << '\n';
  if (!poses_) throw RenderError((directory_ / "frames.csv").string() + ": write failed");
}

PngSink::~PngSink() = default;

void PngSink::finish() {
  writer_->finish();
  poses_.flush();
  if (!poses_) throw RenderError((directory_ / "frames.csv").string() + ": write failed");
}

std::size_t PngSink::images_written() const {
  return writer_->written();
}

}  // namespace bisturi::render
