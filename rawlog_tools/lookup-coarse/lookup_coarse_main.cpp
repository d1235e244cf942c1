// lookup-coarse: online coarse (SeqSLAM) localisation of a query rawlog against a reference
// rawlog; see lookup/coarse/coarse_tool.h and docs/coarse.md.
#include "lookup/coarse/coarse_tool.h"
#include "lookup/common/app.h"

int main(int argc, char** argv) {
    lookup::coarse::CoarseTool tool;
    return lookup::common::runApp("lookup-coarse", tool, argc, argv);
}
