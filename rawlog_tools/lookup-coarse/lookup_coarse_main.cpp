// lookup-coarse: online coarse (SeqSLAM) localisation of a query rawlog against a reference
// rawlog; see lookup/coarse/coarse_tool.h and docs/coarse.md.
#include <iostream>

#include "lookup/coarse/coarse_tool.h"
#include "lookup/common/errors.h"

int main(int argc, char** argv) {
    lookup::coarse::CoarseTool tool;
    if (!tool.initialize(argc, argv)) return tool.exitCode();
    return lookup::common::checkedStdout("lookup-coarse", tool.run(std::cout, std::cerr));
}
