#pragma once
// Whole-file reads (one fread) and buffered writes for the mesh readers and writers.

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <utility>

namespace bisturi::mesh_io {

/// A file's contents in memory of their own (a copy: the file may change after the read).
class FileBytes {
 public:
  explicit FileBytes(std::size_t size);
  ~FileBytes();
  FileBytes(FileBytes&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}
  FileBytes& operator=(FileBytes&&) = delete;

  std::byte* data() { return data_; }
  std::span<const std::byte> bytes() const { return {data_, size_}; }

 private:
  std::byte* data_ = nullptr;
  std::size_t size_ = 0;
};

/// The file's contents; InputError naming the file when it cannot be read.
FileBytes read_file(const std::filesystem::path& file);

/// Appends to a buffer and writes it out in large blocks; SceneError naming the file on failure.
/// close() must be called to learn whether the last block reached the disk.
class FileWriter {
 public:
  explicit FileWriter(const std::filesystem::path& file);
  ~FileWriter();
  FileWriter(const FileWriter&) = delete;
  FileWriter& operator=(const FileWriter&) = delete;

  void write(std::string_view bytes) {
    buffer_ += bytes;
    if (buffer_.size() >= kBlock) flush();
  }
  void close();

 private:
  static constexpr std::size_t kBlock = std::size_t{1} << 20;
  void flush();
  [[noreturn]] void fail(int error) const;

  std::string name_;
  std::FILE* file_ = nullptr;
  std::string buffer_;
};

}  // namespace bisturi::mesh_io
