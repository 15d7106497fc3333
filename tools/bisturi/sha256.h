#pragma once
// SHA-256 (FIPS 180-4) of files and strings, as lowercase hex: the pipeline's input and plan
// checksums (a rerun with the same checksums does no work).

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace bisturi::cli {

class Sha256 {
 public:
  Sha256();
  void update(const void* data, std::size_t size);
  void update(std::string_view text) { update(text.data(), text.size()); }
  /// The digest as 64 hex digits; the object is spent afterwards.
  std::string hex();

 private:
  void block(const std::uint8_t* p);
  std::uint32_t h_[8];
  std::uint8_t buffer_[64];
  std::size_t buffered_ = 0;
  std::uint64_t bytes_ = 0;
};

/// The SHA-256 of a file's bytes; of a folder (a DICOM series): of every regular file under it,
/// in path order, each as its relative path, a NUL and its SHA-256. Throws std::runtime_error
/// naming the path when it cannot be read.
std::string sha256_of_path(const std::filesystem::path& path);

std::string sha256_of_text(std::string_view text);

}  // namespace bisturi::cli
