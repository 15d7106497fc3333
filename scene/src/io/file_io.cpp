#include "file_io.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <new>

#include "bisturi/scene/errors.h"
#include "parse_errors.h"

namespace bisturi::mesh_io {

// Anonymous memory faulted in by one MAP_POPULATE call: first touches page by page cost as much
// as the read itself on virtual machines.
FileBytes::FileBytes(std::size_t size) : size_(size) {
  if (size == 0) return;
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  data_ = static_cast<std::byte*>(p);
}

FileBytes::~FileBytes() {
  if (data_ != nullptr) ::munmap(data_, size_);
}

FileBytes read_file(const std::filesystem::path& file) {
  const std::string name = file.string();
  const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(cat(name, ": cannot open: ", std::strerror(errno)));
  struct FdCloser {
    int fd;
    ~FdCloser() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw InputError(cat(name, ": cannot read: ", std::strerror(errno)));
  if (!S_ISREG(st.st_mode)) throw InputError(cat(name, ": cannot read: not a regular file"));
  FileBytes out(static_cast<std::size_t>(st.st_size));
  const auto size = static_cast<std::size_t>(st.st_size);
  for (std::size_t done = 0; done < size;) {
    const ssize_t n = ::read(fd, out.data() + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw InputError(cat(name, ": cannot read: ", std::strerror(errno)));
    if (n == 0) throw InputError(cat(name, ": cannot read all ", size, " bytes (file changed?)"));
    done += static_cast<std::size_t>(n);
  }
  return out;
}

FileWriter::FileWriter(const std::filesystem::path& file) : name_(file.string()) {
  file_ = std::fopen(name_.c_str(), "wb");
  if (file_ == nullptr) fail(errno);
  buffer_.reserve(kBlock + 4096);
}

FileWriter::~FileWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

void FileWriter::flush() {
  if (!buffer_.empty() && std::fwrite(buffer_.data(), 1, buffer_.size(), file_) != buffer_.size()) {
    fail(errno);
  }
  buffer_.clear();
}

void FileWriter::close() {
  flush();
  std::FILE* f = file_;
  file_ = nullptr;
  if (std::fclose(f) != 0) fail(errno);
}

void FileWriter::fail(int error) const {
  throw SceneError(cat(name_, ": cannot write: ", std::strerror(error)));
}

}  // namespace bisturi::mesh_io
