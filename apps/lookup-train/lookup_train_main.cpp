// lookup-train: self-supervised training of the FCN sample-point selector (paper Sec. III-B)
// and heat maps for every reference of a database (lookup/fcn/train_app.h).
#include "lookup/common/app.h"
#include "lookup/fcn/train_app.h"

int main(int argc, char** argv) {
    lookup::fcn::TrainApp app;
    return lookup::common::runApp("lookup-train", app, argc, argv);
}
