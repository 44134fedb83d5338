#include "fillgs/base/process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <dirent.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <set>
#include <thread>

#include "fillgs/base/error.hpp"

extern char** environ;

namespace fillgs {

namespace {

using Clock = std::chrono::steady_clock;

/// Blocks SIGPIPE in this thread for its lifetime; a SIGPIPE raised meanwhile (a program
/// that stopped reading) is consumed before the old mask comes back.
class NoSigpipe {
 public:
  NoSigpipe() {
    sigemptyset(&pipe_);
    sigaddset(&pipe_, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_, &previous_);
  }
  ~NoSigpipe() {
    const timespec no_wait{0, 0};
    while (sigtimedwait(&pipe_, nullptr, &no_wait) == SIGPIPE) {
    }
    pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
  }
  NoSigpipe(const NoSigpipe&) = delete;
  NoSigpipe& operator=(const NoSigpipe&) = delete;

 private:
  sigset_t pipe_, previous_;
};

struct SpawnSetup {
  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attr;
  SpawnSetup() {
    posix_spawn_file_actions_init(&actions);
    posix_spawnattr_init(&attr);
  }
  ~SpawnSetup() {
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
  }
  SpawnSetup(const SpawnSetup&) = delete;
  SpawnSetup& operator=(const SpawnSetup&) = delete;
};

/// The processes whose parent is this one (from /proc/N/stat), less those in `keep`.
std::vector<pid_t> children_except(const std::set<pid_t>& keep) {
  std::vector<pid_t> out;
  const pid_t self = ::getpid();
  DIR* d = ::opendir("/proc");
  if (!d) return out;
  while (const dirent* e = ::readdir(d)) {
    char* end = nullptr;
    const long pid = std::strtol(e->d_name, &end, 10);
    if (pid <= 0 || *end != '\0' || keep.count(pid_t(pid))) continue;
    std::ifstream in(std::string("/proc/") + e->d_name + "/stat");
    std::string stat;
    std::getline(in, stat);
    const size_t close = stat.rfind(')');  // the name may hold spaces and parentheses
    if (close == std::string::npos) continue;
    char state = 0;
    long ppid = 0;
    if (std::sscanf(stat.c_str() + close + 1, " %c %ld", &state, &ppid) == 2 && ppid == self) out.push_back(pid_t(pid));
  }
  ::closedir(d);
  return out;
}

/// Ends every process the program started: its process group at once, then, round by
/// round, the children this process inherited as their subreaper (those that left the group
/// with setsid, and the orphans of each round's kills), reaping each.
void end_descendants(pid_t group, const std::set<pid_t>& keep) {
  ::kill(-group, SIGKILL);
  for (int round = 0; round < 10000; ++round) {
    const std::vector<pid_t> kids = children_except(keep);
    if (kids.empty()) return;
    for (pid_t k : kids) ::kill(k, SIGKILL);
    for (pid_t k : kids) ::waitpid(k, nullptr, 0);
  }
}

double seconds_left(Clock::time_point deadline) { return std::chrono::duration<double>(deadline - Clock::now()).count(); }

}  // namespace

ProcessResult run_process(const std::vector<std::string>& argv, const ProcessOptions& o) {
  ProcessResult r;
  if (argv.empty() || argv[0].empty()) {
    r.error = "no program named";
    return r;
  }
  int in_pipe[2];
  if (::pipe2(in_pipe, O_CLOEXEC) != 0) {
    r.error = std::string("cannot make a pipe (") + std::strerror(errno) + ")";
    return r;
  }
  SpawnSetup s;
  posix_spawn_file_actions_adddup2(&s.actions, in_pipe[0], 0);
  const std::string out = o.stdout_path.empty() ? "/dev/null" : o.stdout_path;
  const std::string err = o.stderr_path.empty() ? "/dev/null" : o.stderr_path;
  posix_spawn_file_actions_addopen(&s.actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (err == out) posix_spawn_file_actions_adddup2(&s.actions, 1, 2);
  else posix_spawn_file_actions_addopen(&s.actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  // Its own process group (a timeout kills all it started), default signal handling and an
  // empty mask, whatever this process blocks or ignores.
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  posix_spawnattr_setflags(&s.attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  posix_spawnattr_setpgroup(&s.attr, 0);
  posix_spawnattr_setsigmask(&s.attr, &none);
  posix_spawnattr_setsigdefault(&s.attr, &defaults);

  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  NoSigpipe no_sigpipe;
  std::set<pid_t> spared;  // children of this process from before, and the program (reaped below)
  if (o.end_descendants) {
    // Orphans of the program's processes come to this process instead of init, so that a
    // child that called setsid cannot outlive the call.
    static const bool subreaper = ::prctl(PR_SET_CHILD_SUBREAPER, 1) == 0;
    (void)subreaper;
    for (pid_t c : children_except({})) spared.insert(c);
  }
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0].c_str(), &s.actions, &s.attr, args.data(), environ);
  ::close(in_pipe[0]);
  if (rc != 0) {
    ::close(in_pipe[1]);
    r.error = "cannot run '" + argv[0] + "' (" + std::strerror(rc) + ")";
    return r;
  }
  r.started = true;
  spared.insert(pid);
  const bool bounded = o.timeout_seconds > 0;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(bounded ? o.timeout_seconds : 0));
  auto out_of_time = [&] { return bounded && seconds_left(deadline) <= 0; };

  // The input, without blocking past the deadline; a program that stops reading ends it.
  ::fcntl(in_pipe[1], F_SETFL, O_NONBLOCK);
  size_t sent = 0;
  while (sent < o.stdin_data.size() && !out_of_time()) {
    pollfd p{in_pipe[1], POLLOUT, 0};
    const int wait_ms = bounded ? int(std::min(1000.0, std::max(1.0, 1000 * seconds_left(deadline)))) : 1000;
    if (::poll(&p, 1, wait_ms) < 0 && errno != EINTR) break;
    if (p.revents & (POLLERR | POLLHUP)) break;
    if (!(p.revents & POLLOUT)) continue;
    const ssize_t n = ::write(in_pipe[1], o.stdin_data.data() + sent, o.stdin_data.size() - sent);
    if (n > 0) sent += size_t(n);
    else if (n < 0 && errno != EAGAIN && errno != EINTR) break;  // EPIPE: it stopped reading
  }
  ::close(in_pipe[1]);

  int status = 0;
  for (;;) {
    // Waited for without reaping (WNOWAIT): until it is reaped its pid, which names its
    // process group, cannot be reused, so the group is ended before that.
    siginfo_t info{};
    const int w = ::waitid(P_PID, id_t(pid), &info, WEXITED | WNOHANG | WNOWAIT);
    if (w == 0 && info.si_pid == pid) break;
    if (w < 0 && errno != EINTR) {
      r.error = std::string("lost the process (") + std::strerror(errno) + ")";
      return r;
    }
    if (out_of_time()) {
      ::kill(-pid, SIGKILL);
      if (o.end_descendants) {
        // Its children pass to this process only once it has exited, not when the signal
        // is sent: waited for (still unreaped) before they are looked for.
        siginfo_t gone{};
        while (::waitid(P_PID, id_t(pid), &gone, WEXITED | WNOWAIT) < 0 && errno == EINTR) {
        }
        end_descendants(pid, spared);
      }
      ::waitpid(pid, &status, 0);
      r.timed_out = true;
      r.status = -1;
      return r;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (o.end_descendants) end_descendants(pid, spared);
  ::waitpid(pid, &status, 0);
  if (WIFEXITED(status)) r.status = WEXITSTATUS(status);
  else r.status = 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  return r;
}

std::vector<std::string> split_command(const std::string& t, const std::vector<std::pair<std::string, std::string>>& placeholders) {
  const auto refuse = [&](size_t at, const std::string& what) {
    throw_error("command template \"", t, "\": ", what, " at character ", at + 1,
                " is shell syntax, and no shell runs the template; to run a shell on purpose, pass the data as its "
                "arguments: sh -c 'SCRIPT \"$1\" \"$2\"' sh {in} {out}");
  };
  std::vector<std::string> words;
  std::string word;
  bool in_word = false;
  for (size_t i = 0; i < t.size(); ++i) {
    const char c = t[i];
    if (c == ' ' || c == '\t' || c == '\n') {
      if (in_word) words.push_back(word), word.clear(), in_word = false;
      continue;
    }
    if (c == '\'') {
      const size_t end = t.find('\'', i + 1);
      if (end == std::string::npos) throw_error("command template \"", t, "\": a ' at character ", i + 1, " is never closed");
      word += t.substr(i + 1, end - i - 1);
      i = end, in_word = true;
      continue;
    }
    if (c == '"') {
      size_t j = i + 1;
      for (; j < t.size() && t[j] != '"'; ++j) {
        if (t[j] == '\\' && j + 1 < t.size() && std::strchr("\"\\$`", t[j + 1])) {
          word += t[++j];
        } else if (t[j] == '$' || t[j] == '`') {
          refuse(j, std::string("'") + t[j] + "' inside double quotes");
        } else {
          word += t[j];
        }
      }
      if (j >= t.size()) throw_error("command template \"", t, "\": a \" at character ", i + 1, " is never closed");
      i = j, in_word = true;
      continue;
    }
    if (c == '\\') {
      if (i + 1 >= t.size()) throw_error("command template \"", t, "\": it ends in a lone backslash");
      word += t[++i], in_word = true;
      continue;
    }
    if (std::strchr("|&;<>()$`", c)) refuse(i, std::string("'") + c + "'");
    if ((c == '#' || c == '~') && !in_word) refuse(i, std::string("'") + c + "' at the start of a word");
    word += c, in_word = true;
  }
  if (in_word) words.push_back(word);
  if (words.empty()) throw_error("command template \"", t, "\" names no program");
  // One pass over each word: a value that happens to hold another placeholder stays as it is.
  for (std::string& w : words) {
    std::string done;
    for (size_t p = 0; p < w.size();) {
      bool hit = false;
      for (const auto& [key, value] : placeholders)
        if (!key.empty() && w.compare(p, key.size(), key) == 0) {
          done += value, p += key.size(), hit = true;
          break;
        }
      if (!hit) done += w[p++];
    }
    w = std::move(done);
  }
  return words;
}

}  // namespace fillgs
