// Per-test scratch directories for the integration tests, which run the relief executable and
// need files around it.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace relief::test {

// temp/<prefix>-<pid>-<test name>, created, and emptied on the test's first use: a process id is
// reused in time, and a directory left by an earlier run with the same one would hold files a test
// asserts are not written.
inline std::filesystem::path scratchDir(const std::string& prefix) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      (prefix + "-" + std::to_string(::getpid()) + "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  static std::string emptied;
  if (emptied != dir.string()) {
    std::filesystem::remove_all(dir);
    emptied = dir.string();
  }
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace relief::test
