// files:// (pipeline/sources/files_scheme.cpp): what its parameters refuse before a file is read.
// Opening indexes and folders: tests/pipeline/image_folder_source_test.cpp.
#include <gtest/gtest.h>

#include "pipeline/sources.hpp"

namespace augrig::pipeline {
namespace {

TEST(FilesScheme, ParametersThatDoNotFitAreErrors) {
  auto o = open_sources("files://folders?left=/no/L&right=/no/R&bayer=RGGB");
  ASSERT_FALSE(o);
  EXPECT_EQ(
      o.error().message,
      "source URI 'files://folders?left=/no/L&right=/no/R&bayer=RGGB': bayer: expected RG, GR, GB or BG, "
      "got 'RGGB'");
  for (const char* uri :
       {"files://folders?left=/no/L", "files://folders?left=/no/L&right=/no/R&tolerance_us=5",
        "files:///no/index.csv?left=/no/L"}) {
    auto bad = open_sources(uri);
    ASSERT_FALSE(bad) << uri;
    EXPECT_FALSE(bad.error().message.empty());
  }
}

}  // namespace
}  // namespace augrig::pipeline
