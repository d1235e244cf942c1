// lookup-place: builds or evaluates a database's ceiling place index (lookup/place/place_app.h).
#include "lookup/common/errors.h"
#include "lookup/place/place_app.h"

int main(int argc, char** argv) {
    return lookup::common::guardedMain("lookup-place", argc, argv, [&] {
        lookup::place::PlaceApp app;
        if (!app.initialize(argc, argv)) return app.exitCode();
        return app.run();
    });
}
