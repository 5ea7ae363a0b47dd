// The quoting of a file's or a user's text in an error message (message_text.h).
#include "sim/message_text.h"

#include <algorithm>
#include <cstdio>

namespace esim {

namespace {

// appends text[0, n) to out, each byte that is not part of a whole, valid UTF-8 sequence
// (overlong forms and surrogates refused) or is an ASCII control character as \xNN: a
// message stays UTF-8 text (a sweep's seed "\N", yaml-cpp's byte 0x85, was echoed raw)
void appendPrintable(std::string& out, const std::string& text, size_t n) {
  const auto at = [&](size_t i) { return static_cast<unsigned char>(text[i]); };
  for (size_t i = 0; i < n;) {
    const unsigned char c = at(i);
    size_t len = c < 0x80                 ? 1
                 : c >= 0xC2 && c <= 0xDF ? 2
                 : (c >> 4) == 0xE        ? 3
                 : c >= 0xF0 && c <= 0xF4 ? 4
                                          : 0;
    bool ok = len > 0 && i + len <= n;
    for (size_t k = 1; ok && k < len; ++k) ok = (at(i + k) & 0xC0) == 0x80;
    if (ok && len == 1) ok = c >= 0x20 && c != 0x7F;
    if (ok && len == 3) ok = !(c == 0xE0 && at(i + 1) < 0xA0) && !(c == 0xED && at(i + 1) >= 0xA0);
    if (ok && len == 4) ok = !(c == 0xF0 && at(i + 1) < 0x90) && !(c == 0xF4 && at(i + 1) >= 0x90);
    if (!ok) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", c);
      out += hex;
      ++i;
      continue;
    }
    out.append(text, i, len);
    i += len;
  }
}

}  // namespace

std::string quoteInMessage(const std::string& text) {
  constexpr size_t kMax = 60;
  const size_t line = std::min(text.find('\n'), text.size());
  std::string out = "'";
  if (line == text.size() && text.size() <= kMax) {
    appendPrintable(out, text, text.size());
    return out.append("'");
  }
  appendPrintable(out, text, std::min(line, kMax));
  out += " ...' (";
  out += std::to_string(text.size());
  out += " characters)";
  return out;
}

std::string printableInMessage(const std::string& text, size_t maxCharacters) {
  std::string out;
  appendPrintable(out, text, std::min(text.size(), maxCharacters));
  if (text.size() > maxCharacters) out += " ... (" + std::to_string(text.size()) + " characters)";
  return out;
}

std::string printableMessage(const std::string& message, size_t maxCharactersPerLine) {
  std::string out;
  size_t start = 0;
  while (start <= message.size()) {
    const size_t end = std::min(message.find('\n', start), message.size());
    if (start > 0) out += '\n';
    out += printableInMessage(message.substr(start, end - start), maxCharactersPerLine);
    if (end == message.size()) break;
    start = end + 1;
  }
  return out;
}

std::string nameInMessage(const std::string& text) {
  if (text.size() <= 60) {
    std::string printable;
    appendPrintable(printable, text, text.size());
    if (printable == text) return text;
  }
  return quoteInMessage(text);
}

}  // namespace esim
