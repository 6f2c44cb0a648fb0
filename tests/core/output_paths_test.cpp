// Output paths: object names that could leave the output folder are refused, and names are shown printably.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

TEST(FileInFolder, NamesThatLeaveTheFolderAreRefused) {
  EXPECT_EQ(msk::fileInFolder("out", "femur.vtk"), "out/femur.vtk");
  for (const std::string& bad : std::vector<std::string>{"", ".", "..", "../femur.vtk", "a/b.vtk", "a\\b.vtk",
                                                         std::string("fe\0mur", 6), std::string(256, 'a')}) {
    try {
      msk::fileInFolder("out", bad);
      ADD_FAILURE() << "accepted " << msk::printableName(bad);
    } catch (const msk::IoError& e) {
      EXPECT_EQ(e.file(), "out");
      EXPECT_NE(std::string(e.what()).find("would leave the folder"), std::string::npos) << e.what();
    }
  }
}

TEST(FileInFolder, SafeNamesAndPrintableNames) {
  EXPECT_TRUE(msk::isSafeName("femur_right"));
  EXPECT_TRUE(msk::isSafeName("L5.v2-x"));
  EXPECT_FALSE(msk::isSafeName(""));
  EXPECT_FALSE(msk::isSafeName(".hidden"));
  EXPECT_FALSE(msk::isSafeName("-x"));
  EXPECT_FALSE(msk::isSafeName("a b"));
  EXPECT_FALSE(msk::isSafeName("f\xc3\xa9mur"));
  EXPECT_FALSE(msk::isSafeName(std::string(65, 'a')));
  EXPECT_EQ(msk::printableName(std::string("fe\0\x1b[m", 6)), "fe\\x00\\x1b[m");
}

// Messages keep tabs, printable ASCII and UTF-8 whole (no cut), and show every control character, C1 ones in UTF-8
// too, as \xHH: nothing in a log or on a terminal can move the cursor or recolour it.
TEST(FileInFolder, PrintableTextEscapesControlCharactersOnly) {
  EXPECT_EQ(msk::printableText("case f\xc3\xa9mur\tok"), "case f\xc3\xa9mur\tok");
  EXPECT_EQ(msk::printableText("a\x1b[31mred\r\n\x7f"), "a\\x1b[31mred\\x0d\\x0a\\x7f");
  EXPECT_EQ(msk::printableText("\xc2\x9b"
                               "2J"),
            "\\xc2\\x9b"
            "2J");
  EXPECT_EQ(msk::printableText(std::string(300, 'x')).size(), 300u);
}
