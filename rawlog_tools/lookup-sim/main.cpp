// lookup-sim: generates a synthetic mine dataset (lookup/sim/sim_app.h, docs/sim.md).
#include "lookup/common/app.h"
#include "lookup/sim/sim_app.h"

int main(int argc, char** argv) {
    lookup::sim::SimApp app;
    return lookup::common::runApp("lookup-sim", app, argc, argv);
}
