#include "frame_log.h"

#include <png.h>

#include <vector>

namespace bisturi::xrsim {

FrameLog::~FrameLog() {
  if (file_ != nullptr) std::fclose(file_);
}

void FrameLog::open(const std::string& path) {
  if (file_ != nullptr) std::fclose(file_);
  file_ = path.empty() ? nullptr : std::fopen(path.c_str(), "a");
}

void FrameLog::write(const char* event, const std::string& fields) {
  if (file_ == nullptr) return;
  std::fprintf(file_, "{\"event\":\"%s\"%s%s}\n", event, fields.empty() ? "" : ",", fields.c_str());
  std::fflush(file_);
}

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_floats(const float* values, int count) {
  std::string out = "[";
  char number[32];
  for (int i = 0; i < count; ++i) {
    std::snprintf(number, sizeof number, "%.9g", static_cast<double>(values[i]));
    if (i > 0) out += ",";
    out += number;
  }
  return out + "]";
}

bool write_png(const std::string& path, const std::uint8_t* rgba, std::uint32_t width,
               std::uint32_t height) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return false;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  bool ok = false;
  if (info != nullptr && setjmp(png_jmpbuf(png)) == 0) {
    png_init_io(png, file);
    png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (std::uint32_t y = 0; y < height; ++y) {
      png_write_row(png, rgba + std::size_t{y} * width * 4);
    }
    png_write_end(png, nullptr);
    ok = true;
  }
  png_destroy_write_struct(&png, &info);
  std::fclose(file);
  return ok;
}

}  // namespace bisturi::xrsim
