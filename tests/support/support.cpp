#include "lookup/test/support.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <fstream>
#include <iterator>

namespace lookup::test {

namespace fs = std::filesystem;

fs::path freshDir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

std::string readText(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

std::string programPath(const std::string& name) {
    return std::string(LOOKUP_BINARY_DIR) + "/bin/" + name;
}

namespace {

[[noreturn]] void execProgram(const std::string& exe, const std::vector<std::string>& args,
                              const ProgramRun& how) {
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int fd = ::open(how.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(how.stdout_full ? ::open("/dev/full", O_WRONLY) : fd, 1);
    ::dup2(fd, 2);
    if (!how.env.empty()) ::putenv(const_cast<char*>(how.env.c_str()));
    if (how.file_size_limit > 0) {
        std::signal(SIGXFSZ, SIG_IGN);  // inherited through exec
        const rlimit limit{rlim_t(how.file_size_limit), rlim_t(how.file_size_limit)};
        ::setrlimit(RLIMIT_FSIZE, &limit);
    }
    ::execv(exe.c_str(), argv.data());
    _exit(127);
}

}  // namespace

int runProgram(const std::string& name, const std::vector<std::string>& args,
               const ProgramRun& how) {
    const std::string exe = programPath(name);
    const pid_t pid = ::fork();
    if (pid == 0) execProgram(exe, args, how);
    int status = 0;
    for (;;) {
        const pid_t done = ::waitpid(pid, &status, how.kill_when ? WNOHANG : 0);
        if (done == pid) break;
        if (how.kill_when && how.kill_when()) {
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            break;
        }
        ::usleep(10000);
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

int runProgram(const std::string& name, const std::vector<std::string>& args, const fs::path& log,
               long file_size_limit, const std::function<bool()>& kill_when) {
    ProgramRun how;
    how.log = log;
    how.file_size_limit = file_size_limit;
    how.kill_when = kill_when;
    return runProgram(name, args, how);
}

AppRun runApp(const char* program, common::App& app, const std::vector<std::string>& args) {
    std::vector<const char*> argv{program};
    for (const auto& a : args) argv.push_back(a.c_str());
    AppRun r;
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    r.code = common::runApp(program, app, int(argv.size()), argv.data());
    std::fflush(stdout);
    std::fflush(stderr);
    r.out = testing::internal::GetCapturedStdout();
    r.err = testing::internal::GetCapturedStderr();
    return r;
}

}  // namespace lookup::test
