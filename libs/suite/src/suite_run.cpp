#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "lookup/common/rawlog_io.h"
#include "lookup/suite/suite.h"
#include "suite_internal.h"

namespace lookup::suite {
namespace fs = std::filesystem;

namespace {

struct PendingJob {
    std::size_t condition_index = 0;
    std::uint64_t seed = 0;
    std::string dir;
};

/// The child: its output goes to log.txt, its result to result.json; it never returns.
[[noreturn]] void runChild(const SuiteOptions& suite, const PendingJob& job) {
    const std::string log_path = job.dir + "/log.txt";
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
        ::close(fd);
    }
    const JobResult r = runJob(suite, suite.conditions[job.condition_index], job.seed, job.dir);
    int code = 0;
    try {
        common::writeFileAtomically(job.dir + "/result.json", toJson(r).dump(2) + "\n");
    } catch (const std::exception& e) {
        std::cerr << "lookup-suite: " << e.what() << "\n";
        code = 3;
    }
    std::cout.flush();
    std::cerr.flush();
    ::_exit(code);
}

pid_t startJob(const SuiteOptions& suite, const PendingJob& job) {
    std::error_code ec;
    fs::remove_all(job.dir, ec);
    fs::create_directories(job.dir, ec);
    if (ec) throw std::runtime_error(job.dir + ": cannot create: " + ec.message());
    std::cout.flush();
    std::cerr.flush();
    const pid_t pid = ::fork();
    if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    if (pid == 0) runChild(suite, job);
    return pid;
}

std::string lastLine(const std::string& path) {
    std::ifstream in(path);
    std::string line, last;
    while (std::getline(in, line)) {
        if (!line.empty()) last = line;
    }
    return last.substr(0, 300);
}

/// The child's result, or a failed row saying how the child ended.
JobResult collect(const SuiteOptions& suite, const PendingJob& job, int status) {
    JobResult r;
    r.condition = suite.conditions[job.condition_index].name;
    r.seed = job.seed;
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
        try {
            std::ifstream in(job.dir + "/result.json");
            JobResult done = jobFromJson(nlohmann::json::parse(in));
            // A step's own message is often only in the log (an app's refusal, say).
            if (!done.ok) done.reason += " (log.txt: " + lastLine(job.dir + "/log.txt") + ")";
            return done;
        } catch (const std::exception& e) {
            r.reason = job.dir + "/result.json: unreadable: " + e.what();
            return r;
        }
    }
    r.reason = WIFSIGNALED(status) ? "crashed with signal " + std::to_string(WTERMSIG(status))
                                   : "exited with code " + std::to_string(WEXITSTATUS(status));
    r.reason += " (" + job.dir + "/log.txt: " + lastLine(job.dir + "/log.txt") + ")";
    return r;
}

std::string describe(const JobResult& r) {
    return r.condition + " seed " + std::to_string(r.seed) + ": " +
           (r.ok ? "ok" : "FAILED " + r.reason) + " (" + std::to_string(int(r.wall_s)) + " s)";
}

}  // namespace

std::vector<JobResult> runSuite(const SuiteOptions& suite, const std::string& out_dir, int parallel,
                                std::ostream& log) {
    std::vector<PendingJob> queue;
    for (std::size_t c = 0; c < suite.conditions.size(); ++c) {
        for (auto seed : suite.seeds) {
            queue.push_back(
                {c, seed,
                 out_dir + "/jobs/" + suite.conditions[c].name + "/seed-" + std::to_string(seed)});
        }
    }
    std::map<pid_t, PendingJob> running;
    std::vector<JobResult> results;
    std::size_t next = 0;
    while (next < queue.size() || !running.empty()) {
        while (running.size() < static_cast<std::size_t>(std::max(1, parallel)) &&
               next < queue.size()) {
            running[startJob(suite, queue[next])] = queue[next];
            ++next;
        }
        int status = 0;
        const pid_t pid = ::waitpid(-1, &status, 0);
        if (pid < 0) {
            if (errno == EINTR) continue;
            throw std::runtime_error(std::string("waitpid: ") + std::strerror(errno));
        }
        const auto it = running.find(pid);
        if (it == running.end()) continue;
        results.push_back(collect(suite, it->second, status));
        running.erase(it);
        log << describe(results.back()) << std::endl;
        writeSuiteReport(suite, results, out_dir);
    }
    std::map<std::string, std::size_t> order;
    for (std::size_t c = 0; c < suite.conditions.size(); ++c) order[suite.conditions[c].name] = c;
    std::sort(results.begin(), results.end(), [&](const JobResult& a, const JobResult& b) {
        return std::make_pair(order[a.condition], a.seed) <
               std::make_pair(order[b.condition], b.seed);
    });
    writeSuiteReport(suite, results, out_dir);
    return results;
}

}  // namespace lookup::suite
