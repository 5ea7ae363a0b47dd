// fuzz_common.h - what every libFuzzer target of tests/fuzz shares.
//
// A target hands one input to one reader. The expected rejection is an esim::Error of kind
// Input (bad input) or Run whose message is fit to print (messageProblem); everything else is
// a finding that stops the fuzzer: a crash, a sanitizer report, another exception
// (std::terminate), an Internal error (a broken invariant: the input got past the checks), a
// message that echoes the input raw (megabytes of it, or bytes that are not text) or a broken
// oracle (finding()).
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "sim/core_error.h"
#include "sim/message_text.h"

namespace esim::fuzz {

// stops the run with a message: libFuzzer saves the input as crash-<sha1>
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "fuzz finding: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

// what is wrong with a rejection's message, or "" when it is fit to print: UTF-8 text
// without control characters but newlines (message_text.h: the input's text is quoted, not
// echoed), of at most kMaxMessageBytes (a message quoting a whole input was megabytes)
constexpr std::size_t kMaxMessageBytes = 4096;
inline std::string messageProblem(const std::string& m) {
  if (m.size() > kMaxMessageBytes)
    return std::to_string(m.size()) + " bytes (at most " + std::to_string(kMaxMessageBytes) + ")";
  // printed as it is: each line unchanged by the escaping message_text.h applies
  if (printableMessage(m, kMaxMessageBytes) == m) return "";
  return "bytes that are not text, or control characters, in " + printableMessage(m, 300);
}

// runs body(); an Input or Run error is the expected rejection (returns false) when its
// message is fit to print (messageProblem); an Internal error is a finding; any other
// exception escapes (a finding too)
template <class Body>
bool accepts(Body&& body) {
  try {
    body();
    return true;
  } catch (const Error& e) {
    if (e.kind() == ErrorKind::Internal) finding(std::string("internal error: ") + e.what());
    const std::string problem = messageProblem(e.what());
    if (!problem.empty())
      finding("a rejection's message is not fit to print (" + problem +
              "): " + std::string(e.what()).substr(0, 300));
    return false;
  }
}

// the input as a file named esim_fuzz_<pid><extension> in the temp folder (readers take paths)
inline std::string writeTemp(const std::uint8_t* data, std::size_t size,
                             const std::string& extension) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("esim_fuzz_" + std::to_string(::getpid()) + extension))
                               .string();
  std::ofstream os(path, std::ios::binary | std::ios::trunc);
  os.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  os.close();
  if (!os) finding("cannot write the temp file " + path);
  return path;
}

}  // namespace esim::fuzz
