// prtbake_peak_rss RESULT CMD ARGS...: runs CMD with ARGS (fork and exec) and writes to the
// file RESULT "EXIT PEAK_KIB": its exit code (128 + the signal for a signal) and its own peak
// resident size from wait4. A small process of its own, because a child's peak resident size
// counts the memory of the process it was forked or spawned from, up to its exec: measured
// from a test that holds 140 MiB, every child would show 140 MiB.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: prtbake_peak_rss RESULT CMD [ARGS...]\n");
    return 2;
  }
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execv(argv[2], argv + 2);
    ::_exit(127);
  }
  int status = 0;
  rusage ru{};
  if (pid < 0 || ::wait4(pid, &status, 0, &ru) != pid) return 2;
  FILE* f = std::fopen(argv[1], "w");
  if (!f) return 2;
  std::fprintf(f, "%d %ld\n", WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), ru.ru_maxrss);
  return std::fclose(f) == 0 ? 0 : 2;
}
