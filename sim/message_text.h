// message_text.h - text read from a file or given by a user, quoted in an error message.
//
// A message names what it refuses, but the text refused can be anything: a whole file read
// as the wrong kind (an OBJ as a scenario, a 5 MB line of a path CSV), bytes that are not
// UTF-8 (a binary file, yaml-cpp's decoding of "\N" to the byte 0x85), control characters.
// The readers (esim_io), the app and the core's own checks of names quote such text here, so a
// message stays short UTF-8 text whatever the input. Plain text only: no file format.
#pragma once

#include <cstddef>
#include <string>

namespace esim {

// a value as quoted in an error message: 'text', or its first line cut at 60 characters with
// its length ("'v -0.0175 0.0417 ...' (511234 characters)": a whole OBJ file read as a
// scenario was quoted whole); bytes that are not UTF-8 text, and control characters, as \xNN
std::string quoteInMessage(const std::string& text);

// text as it is when it is one short line of printable UTF-8 (at most 60 characters, none a
// control character), else quoteInMessage(text): a key path or a --set override reads as it
// was typed, and nothing else can make a message long or unprintable
std::string nameInMessage(const std::string& text);

// a library's own message (yaml-cpp's, assimp's, an exception's what()), which may hold the
// input's bytes (assimp names a mesh by the file's text, yaml-cpp an escape by its byte): as
// it is, bytes that are not UTF-8 text and control characters written \xNN, cut after
// maxCharacters with its length
std::string printableInMessage(const std::string& text, std::size_t maxCharacters = 300);

// a whole message as printed (esim's last word on stderr): each line printableInMessage with
// a cap of maxCharactersPerLine, the net under the quoting above (a file name with a
// terminal's escape, a path of thousands of characters)
std::string printableMessage(const std::string& message, std::size_t maxCharactersPerLine = 2000);

// a path the user gave, as a status line shows it ("wrote out/x/timing.csv", the summary's
// outputs): printableInMessage with the net's cap, so a folder named with a terminal's escape
// prints as \x1B[31m, not as a colour, and a path of 5000 characters as its first 2000
inline std::string printablePath(const std::string& path) { return printableInMessage(path, 2000); }

}  // namespace esim
