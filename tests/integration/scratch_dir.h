// Per-test scratch directories for the integration tests, which run the relief executable and
// need files around it.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace relief::test {

// Removes the scratch directory of a test that passed when it ends; a failed test's is kept for
// a look. Registered once, before the tests run, by the inline variable below.
class ScratchCleaner : public ::testing::EmptyTestEventListener {
 public:
  static std::string& current() {
    static std::string dir;
    return dir;
  }
  void OnTestEnd(const ::testing::TestInfo& info) override {
    if (!current().empty() && info.result()->Passed()) {
      std::error_code ignored;
      std::filesystem::remove_all(current(), ignored);
    }
    current().clear();
  }
};
inline const bool kScratchCleanerRegistered = [] {
  ::testing::UnitTest::GetInstance()->listeners().Append(new ScratchCleaner);
  return true;
}();

// temp/<prefix>-<pid>-<test name>, created, and emptied on the test's first use: a process id is
// reused in time, and a directory left by an earlier run with the same one would hold files a test
// asserts are not written.
inline std::filesystem::path scratchDir(const std::string& prefix) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      (prefix + "-" + std::to_string(::getpid()) + "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  if (ScratchCleaner::current() != dir.string()) {
    std::filesystem::remove_all(dir);
    ScratchCleaner::current() = dir.string();
  }
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace relief::test
