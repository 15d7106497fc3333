#include "text_scanner.h"

#include <cstring>

namespace bisturi::mesh_io {

bool TextScanner::next_line() {
  if (next_ >= text_.size()) {
    in_line_ = false;
    cursor_ = line_end_ = line_start_ = next_ = text_.size();
    return false;
  }
  line_start_ = next_;
  line_number_ = next_line_number_;
  std::size_t pos = next_;
  std::size_t end = 0;
  for (;;) {
    const void* nl = std::memchr(text_.data() + pos, '\n', text_.size() - pos);
    end = nl != nullptr ? static_cast<std::size_t>(static_cast<const char*>(nl) - text_.data())
                        : text_.size();
    ++next_line_number_;
    next_ = nl != nullptr ? end + 1 : end;
    if (!options_.backslash_continues || nl == nullptr) break;
    std::size_t last = end;
    if (last > pos && text_[last - 1] == '\r') --last;
    if (last == pos || text_[last - 1] != '\\') break;
    pos = next_;
    if (pos >= text_.size()) break;
  }
  line_end_ = end;
  if (options_.comment != '\0') {
    const void* c = std::memchr(text_.data() + line_start_, options_.comment, end - line_start_);
    if (c != nullptr)
      line_end_ = static_cast<std::size_t>(static_cast<const char*>(c) - text_.data());
  }
  cursor_ = line_start_;
  in_line_ = true;
  return true;
}

bool TextScanner::is_space(std::size_t i) const {
  const char c = text_[i];
  if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f') return true;
  if (c != '\\' || !options_.backslash_continues) return false;
  // A continuation backslash separates tokens like the line break it hides.
  const std::size_t n = i + 1;
  return n == line_end_ || text_[n] == '\n' ||
         (text_[n] == '\r' && (n + 1 == line_end_ || text_[n + 1] == '\n'));
}

std::string_view TextScanner::token() {
  while (cursor_ < line_end_ && is_space(cursor_))
    ++cursor_;
  const std::size_t start = cursor_;
  while (cursor_ < line_end_ && !is_space(cursor_))
    ++cursor_;
  return text_.substr(start, cursor_ - start);
}

std::string_view TextScanner::token_across_lines() {
  if (!in_line_ && !next_line()) return {};
  for (;;) {
    const std::string_view t = token();
    if (!t.empty()) return t;
    if (!next_line()) return {};
  }
}

}  // namespace bisturi::mesh_io
