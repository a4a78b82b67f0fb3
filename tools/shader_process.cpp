// relief's shader provider through a reliefc child process (see shader_process.h).
#include "tools/shader_process.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>

#include "runtime/shader_object.h"

extern char** environ;

namespace relief::tools {
namespace {

// reliefc beside the running executable (both are built into build/bin and installed together).
std::string siblingCompiler() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const std::filesystem::path sibling = self.parent_path() / "reliefc";
  return std::filesystem::is_regular_file(sibling, ec) ? sibling.string() : std::string();
}

// Runs argv[0] with standard output into a pipe; returns what it wrote and its exit status
// (-1 with *error when it could not run or was killed).
int runCapturingOutput(const std::vector<std::string>& args, bool searchPath, std::string* output,
                       std::string* error) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    *error = std::string("cannot create a pipe: ") + std::strerror(errno);
    return -1;
  }
  // The child reads nothing (stdin from /dev/null) and starts with default signal handling and an
  // empty mask, whatever relief inherited.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t all, none;
  sigfillset(&all), sigemptyset(&none);
  posix_spawnattr_setsigdefault(&attr, &all);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = searchPath ? posix_spawnp(&pid, argv[0], &actions, &attr, argv.data(), environ)
                            : posix_spawn(&pid, argv[0], &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    *error = "cannot run the shader compiler '" + args[0] + "': " + std::strerror(rc);
    return -1;
  }
  char buffer[1 << 16];
  int readError = 0;
  for (;;) {
    const ssize_t n = read(fds[0], buffer, sizeof buffer);
    if (n > 0) {
      output->append(buffer, size_t(n));
    } else if (n == 0) {
      break;
    } else if (errno != EINTR) {
      readError = errno;
      break;
    }
  }
  close(fds[0]);  // the child, if still writing, stops on a broken pipe
  int status = 0;
  pid_t waited;
  while ((waited = waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (waited != pid) {
    *error = "cannot wait for the shader compiler '" + args[0] + "': " + std::strerror(errno);
    return -1;
  }
  if (readError) {
    *error = "cannot read the output of the shader compiler '" + args[0] + "': " + std::strerror(readError);
    return -1;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  *error = "the shader compiler '" + args[0] + "' was killed by signal " +
           std::to_string(WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  return -1;
}

}  // namespace

ShaderCompilerProcess::ShaderCompilerProcess(ShaderCompilerOptions options) : options_(std::move(options)) {}

ShaderCompilerProcess::CachedFile ShaderCompilerProcess::compile(const std::string& path) {
  CachedFile cached;
  std::string compiler = options_.compiler;
  if (compiler.empty())
    if (const char* env = std::getenv("RELIEF_COMPILER"); env && *env) compiler = env;
  if (compiler.empty()) compiler = siblingCompiler();
#ifdef RELIEF_COMPILER_BUILD_PATH
  std::error_code ec;
  if (compiler.empty() && std::filesystem::is_regular_file(RELIEF_COMPILER_BUILD_PATH, ec))
    compiler = RELIEF_COMPILER_BUILD_PATH;
#endif
  if (compiler.empty()) compiler = "reliefc";
  const bool searchPath = compiler.find('/') == std::string::npos;  // a bare name is looked up on PATH
  std::vector<std::string> args = {compiler, "--emit-bundle", "--color=never"};
  for (const std::string& dir : options_.includeDirs) args.push_back("-I"), args.push_back(dir);
  if (options_.noWarnings) args.push_back("-w");
  args.push_back("--");
  args.push_back(path);
  std::cerr << std::flush;  // our messages before the child's
  std::string bundle, error;
  const int status = runCapturingOutput(args, searchPath, &bundle, &error);
  if (status < 0) {
    cached.error = error;
    return cached;
  }
  if (status != 0) return cached;  // reliefc has said why on standard error
  if (!runtime::loadShaderBundle(bundle, &cached.shaders, &error)) {
    cached.error = "cannot load the code reliefc compiled from '" + path + "': " + error;
    cached.shaders.clear();
    return cached;
  }
  cached.ok = true;
  return cached;
}

std::shared_ptr<const runtime::CompiledShader> ShaderCompilerProcess::find(std::string_view name,
                                                                           std::span<const std::string> searchPath,
                                                                           std::string* error) {
  std::string path, shaderName;
  if (!runtime::locateShaderFile(name, searchPath, &path, &shaderName, error)) return nullptr;
  auto it = cache_.find(path);
  if (it == cache_.end()) it = cache_.emplace(path, compile(path)).first;
  const CachedFile& file = it->second;
  if (!file.ok) {
    if (error)
      *error = file.error.empty() ? "shader '" + std::string(name) + "' failed to compile (" + path + ")" : file.error;
    return nullptr;
  }
  for (const auto& s : file.shaders)
    if (s->name() == shaderName) return s;
  if (error) *error = runtime::noShaderNamed(path, shaderName, file.shaders);
  return nullptr;
}

}  // namespace relief::tools
