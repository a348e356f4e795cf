// Lines of a text input (an ini file, an input list, a text catalogue) read with a bound on their
// length: std::getline on a file with no newline (/dev/zero, a binary file named by mistake) grows
// its string until memory runs out, so a bad file would hang the run instead of being an error.
#pragma once

#include <cstddef>
#include <istream>
#include <string>

namespace stampede::io {

// Longer than any line of a real configuration, list or catalogue (a 5 MB ini value is still read,
// and named in its error); short enough to read from /dev/zero in a fraction of a second.
inline constexpr std::size_t kMaxTextLine = std::size_t{1} << 24;

enum class TextLine { kLine, kEnd, kTooLong };

// The next line of `in` into *line, without its '\n'. kEnd at the end of the stream with nothing
// read; kTooLong once a line passes max_bytes (the rest is left unread).
// A read error (a directory) sets in's badbit, as getline does.
inline TextLine read_text_line(std::istream& in, std::string* line, std::size_t max_bytes = kMaxTextLine) {
  line->clear();
  for (;;) {
    const std::istream::int_type c = in.get();
    if (c == std::istream::traits_type::eof()) return line->empty() ? TextLine::kEnd : TextLine::kLine;
    if (c == '\n') return TextLine::kLine;
    if (line->size() == max_bytes) return TextLine::kTooLong;
    line->push_back(static_cast<char>(c));
  }
}

}  // namespace stampede::io
