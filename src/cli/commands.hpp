#pragma once
// Commands implemented outside cli.cpp; each returns the process exit status.
#include <ostream>
#include <string>
#include <vector>

namespace fillgs::cli {

int cmd_explore(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_select(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_finetune(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_eval(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_bench(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
int cmd_run(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace fillgs::cli
