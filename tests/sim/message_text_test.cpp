// Tests for sim/message_text.cpp: a file's or a user's text in an error message stays one
// short line of UTF-8 text.
#include "sim/message_text.h"

#include <gtest/gtest.h>

#include <string>

namespace esim {
namespace {

TEST(MessageText, LongValuesAreQuotedShort) {
  EXPECT_EQ(quoteInMessage("high"), "'high'");
  EXPECT_EQ(quoteInMessage(""), "''");
  EXPECT_EQ(quoteInMessage(std::string(60, 'x')), "'" + std::string(60, 'x') + "'");
  EXPECT_EQ(quoteInMessage(std::string(61, 'x')),
            "'" + std::string(60, 'x') + " ...' (61 characters)");
  EXPECT_EQ(quoteInMessage("first line\nsecond"), "'first line ...' (17 characters)");
  // bytes that are not UTF-8 text, and control characters, escaped: a message stays text
  // (a sweep file's seed "\N", which yaml-cpp decodes to the byte 0x85, was echoed raw)
  EXPECT_EQ(quoteInMessage("\x85"), "'\\x85'");
  EXPECT_EQ(quoteInMessage("a\tb\x7f"), "'a\\x09b\\x7F'");
  EXPECT_EQ(quoteInMessage("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x94\xa5"),
            "'caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x94\xa5'");  // whole sequences kept
  EXPECT_EQ(quoteInMessage("\xc0\x80\xed\xa0\x80"),          // overlong NUL, a surrogate
            "'\\xC0\\x80\\xED\\xA0\\x80'");
  // a sequence cut at the 60th byte is not left half
  EXPECT_EQ(quoteInMessage(std::string(59, 'x') + "\xc3\xa9yz"),
            "'" + std::string(59, 'x') + "\\xC3 ...' (63 characters)");
}

// a name reads as typed while it is short printable text; anything else is quoted
TEST(MessageText, NamesReadAsTypedUnlessTheyCannot) {
  EXPECT_EQ(nameInMessage("tool.voltage_v"), "tool.voltage_v");
  EXPECT_EQ(nameInMessage("tool.voltage_v=60"), "tool.voltage_v=60");
  EXPECT_EQ(nameInMessage("caf\xc3\xa9"), "caf\xc3\xa9");
  EXPECT_EQ(nameInMessage(std::string(60, 'k')), std::string(60, 'k'));
  EXPECT_EQ(nameInMessage(std::string(61, 'k')), quoteInMessage(std::string(61, 'k')));
  EXPECT_EQ(nameInMessage("power_den\tsity"), "'power_den\\x09sity'");
  EXPECT_EQ(nameInMessage("a\x1b[2Jb"), "'a\\x1B[2Jb'");  // a terminal's escape
  EXPECT_EQ(nameInMessage("two\nlines"), "'two ...' (9 characters)");
  EXPECT_EQ(nameInMessage(""), "");
}

// the net under them: a whole message as printed, line by line, each escaped and cut at 2000
TEST(MessageText, PrintedMessagesAreEscapedLineByLine) {
  EXPECT_EQ(printableMessage("a.yaml: cannot open\nhint"), "a.yaml: cannot open\nhint");
  EXPECT_EQ(printableMessage("/tmp/x\x1b[31m.yaml: no\n\x85"), "/tmp/x\\x1B[31m.yaml: no\n\\x85");
  const std::string cut = printableMessage(std::string(5000, 'q') + "\nnext");
  EXPECT_EQ(cut, std::string(2000, 'q') + " ... (5000 characters)\nnext");
  EXPECT_EQ(printableMessage(""), "");
  EXPECT_EQ(printableMessage("end\n"), "end\n");
}

}  // namespace
}  // namespace esim
