// lookup-suite: the measuring stick over conditions x seeds (see lookup/suite/suite_app.h).
#include "lookup/suite/suite_app.h"

int main(int argc, char** argv) {
    lookup::suite::SuiteApp app({LOOKUP_SOURCE_SHARE_DIR, LOOKUP_INSTALL_SHARE_DIR});
    if (!app.initialize(argc, argv)) return app.exitCode();
    return app.run();
}
