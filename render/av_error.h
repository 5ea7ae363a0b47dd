// av_error.h - libav error codes as text (shared by the PNG and video code).
#pragma once

extern "C" {
#include <libavutil/error.h>
}

#include <string>

namespace esim {

// the message av_strerror gives for a negative libav return code
inline std::string avError(int code) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(code, buf, sizeof buf);
  return buf;
}

}  // namespace esim
