#pragma once
// Lines and whitespace-separated tokens of a text held in memory, without copies. Lines end at
// '\n' (a '\r' before it is whitespace); numbering is 1-based.

#include <cstddef>
#include <string_view>

namespace bisturi::mesh_io {

struct ScanOptions {
  char comment = '\0';               ///< a line ends at this character ('\0': no comments)
  bool backslash_continues = false;  ///< a '\' at a line's end joins the next line (OBJ)
};

class TextScanner {
 public:
  explicit TextScanner(std::string_view text, ScanOptions options = {},
                       std::size_t first_line_number = 1)
      : text_(text), options_(options), next_line_number_(first_line_number) {}

  /// Moves to the next line; false at the end of the text.
  bool next_line();
  /// The next token of the current line; empty when the line has no more.
  std::string_view token();
  /// The next token of this or a later line; empty at the end of the text.
  std::string_view token_across_lines();

  /// 1-based number of the current line (its first physical line when continued).
  std::size_t line_number() const { return line_number_; }
  /// Offset of the current line's start in the text.
  std::size_t line_offset() const { return line_start_; }
  /// Offset just past the current line's '\n' (the end of the text when it has none).
  std::size_t next_line_offset() const { return next_; }
  /// The rest of the current line after the last token read.
  std::string_view rest() const { return text_.substr(cursor_, line_end_ - cursor_); }

 private:
  bool is_space(std::size_t i) const;

  std::string_view text_;
  ScanOptions options_;
  std::size_t next_line_number_;
  std::size_t line_number_ = 0;
  std::size_t line_start_ = 0;
  std::size_t line_end_ = 0;  // content end (comment cut), the '\n' excluded
  std::size_t cursor_ = 0;
  std::size_t next_ = 0;  // start of the following line
  bool in_line_ = false;
};

}  // namespace bisturi::mesh_io
