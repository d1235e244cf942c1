// lookup-suite: the measuring stick over conditions x seeds (see lookup/suite/suite_app.h).
#include "lookup/common/app.h"
#include "lookup/common/share_dirs.h"
#include "lookup/suite/suite_app.h"

int main(int argc, char** argv) {
    lookup::suite::SuiteApp app(lookup::common::shareDirectories());
    return lookup::common::runApp("lookup-suite", app, argc, argv);
}
