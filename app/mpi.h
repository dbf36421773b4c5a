// dejag-mpi's start and end (app/mpi_communicator.cpp): MPI is initialised before the command line is
// parsed, the job's communicator installed (base/communicator.h), and a rank that fails ends the job.
#pragma once

namespace dejag::cli {

class MpiSession {
  public:
    MpiSession(int& argc, char**& argv);
    // MPI_Finalize, or MPI_Abort of the whole job when this rank ends with an error; returns `code`.
    int finish(int code);
};

}  // namespace dejag::cli
