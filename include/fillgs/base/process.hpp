#pragma once
// Starting other programs (gnuplot for the charts, `finetune --refiner external`) without a
// shell: an argument vector goes to posix_spawnp as it is, so no byte of a path or of any
// other data is ever read as shell syntax.
#include <string>
#include <vector>

namespace fillgs {

struct ProcessOptions {
  std::string stdin_data;   ///< written to the program's standard input, then closed
  std::string stdout_path;  ///< where its standard output goes ("": /dev/null)
  std::string stderr_path;  ///< where its standard error goes ("": /dev/null; may equal stdout_path)
  double timeout_seconds = 0;  ///< > 0: the program's process group is killed after this long
  /// When the program exits or times out, end every process it started: its process group,
  /// and, with this process as their subreaper (PR_SET_CHILD_SUBREAPER), those that left the
  /// group (setsid) or were orphaned. It assumes no other thread of this process starts
  /// children meanwhile (its children from before the call are spared).
  bool end_descendants = false;
};

struct ProcessResult {
  bool started = false;  ///< false: it could not be started (`error` says why)
  bool timed_out = false;
  int status = -1;       ///< its exit status; 128 + N when signal N ended it
  std::string error;     ///< why it could not be started
};

/// Runs `argv` (argv[0] looked up in PATH when it holds no '/') in a process group of its
/// own and waits for it. SIGPIPE is not raised in the caller if the program stops reading
/// its input. Never throws for the program's failure: the result says what happened.
ProcessResult run_process(const std::vector<std::string>& argv, const ProcessOptions& options = {});

/// Splits a command template into words as a POSIX shell would split a simple command,
/// without running one: blanks separate words; '…' keeps everything literally; "…" keeps
/// everything but \" \\ \$ \` literally; \ outside quotes takes the next character
/// literally. Operators a shell would interpret (| & ; < > ( ) $ ` and a leading # or ~)
/// outside quotes are refused with one line that says how to run a shell on purpose:
/// `sh -c 'SCRIPT "$1" "$2"' sh {in} {out}`, where the data arrive as arguments.
/// Each placeholder ("{in}") found in a word is replaced by its value afterwards, so a
/// value is never split or interpreted.
std::vector<std::string> split_command(const std::string& command_template,
                                       const std::vector<std::pair<std::string, std::string>>& placeholders = {});

}  // namespace fillgs
