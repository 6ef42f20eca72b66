#include "simulate/simulate_args.h"

#include "opl/io/atomic_file.h"
#include "opl/io/provenance_stamp.h"

namespace opl {
namespace simulate_cli {

Status WriteStamped(const Args& args, const std::string& path, const std::string& contents) {
  opl::Result<std::string> stamped = opl::StampProvenance(path, contents, args.provenance);
  if (!stamped.ok()) return stamped.status();
  return opl::WriteFileAtomically(path, *stamped);
}

void AddDesignAndOut(CLI::App* command, Args* args, const std::string& out_help) {
  command
      ->add_option("--design", args->design_path,
                   "Module design JSON (docs/simulation.md, 'Module design JSON')")
      ->required()
      ->type_name("FILE");
  command->add_option("--out", args->out_path, out_help)->required()->type_name("FILE");
}

}  // namespace simulate_cli
}  // namespace opl
