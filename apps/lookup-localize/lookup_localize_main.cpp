// lookup-localize: precise localisation of a query rawlog against a reference database
// (lookup/localize/localize_app.h).
#include "lookup/common/app.h"
#include "lookup/localize/localize_app.h"

int main(int argc, char** argv) {
    lookup::localize::stopOnSignals();
    lookup::localize::LocalizeApp app;
    return lookup::common::runApp("lookup-localize", app, argc, argv);
}
