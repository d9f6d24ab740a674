/* One HDF5 file from R processes, two ways (issue 20: "parallel HDF5 or gathering on one rank: choose by
 * measurement"): each rank holds n / R values of `cols` per-vehicle columns (doubles) and
 *   gather:   rank 0 receives each other rank's share in turn (MPI_Recv into one share's buffer) and writes it as a
 *             hyperslab with the serial (sec2) driver, as `wavefuel-mpi run` writes /vehicles (src/core/sim.c,
 *             wf_sim_shares);
 *   parallel: every rank writes its own hyperslab through MPI-IO (H5Pset_fapl_mpio), collectively.
 * Prints the wall time of each (file created to file closed, the slowest rank), best of `repeats`. Build and run:
 * bench/mpi_ring/h5_write.sh. Usage: h5_write N COLS REPEATS DIR */
#include <hdf5.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>

static double now(void) { return MPI_Wtime(); }

static hid_t column(hid_t f, int j, hsize_t n)
{
    char name[32];
    snprintf(name, sizeof name, "c%d", j);
    hid_t sp = H5Screate_simple(1, &n, NULL);
    hid_t d = H5Dcreate2(f, name, H5T_NATIVE_DOUBLE, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Sclose(sp);
    return d;
}

static void put(hid_t d, hsize_t lo, hsize_t m, const double *v, hid_t xfer)
{
    hid_t fs = H5Dget_space(d), ms = H5Screate_simple(1, &m, NULL);
    H5Sselect_hyperslab(fs, H5S_SELECT_SET, &lo, NULL, &m, NULL);
    H5Dwrite(d, H5T_NATIVE_DOUBLE, ms, fs, xfer, v);
    H5Sclose(ms), H5Sclose(fs);
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (argc < 5) {
        if (!rank) fprintf(stderr, "usage: h5_write N COLS REPEATS DIR\n");
        MPI_Finalize();
        return 2;
    }
    hsize_t n = (hsize_t)atoll(argv[1]);
    int cols = atoi(argv[2]), repeats = atoi(argv[3]);
    char path[4096];
    hsize_t lo = n * (hsize_t)rank / (hsize_t)size, hi = n * (hsize_t)(rank + 1) / (hsize_t)size, most = n / size + 1;
    double *mine = malloc((hi - lo) * sizeof *mine), *buf = malloc(most * sizeof *buf);
    for (hsize_t i = lo; i < hi; i++) mine[i - lo] = (double)i * 0.5;
    double best[2] = {1e30, 1e30};
    for (int r = 0; r < repeats; r++) {
        /* gather onto rank 0, a share at a time */
        snprintf(path, sizeof path, "%s/gather.h5", argv[4]);
        MPI_Barrier(MPI_COMM_WORLD);
        double t0 = now();
        if (rank == 0) {
            hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
            for (int j = 0; j < cols; j++) {
                hid_t d = column(f, j, n);
                put(d, lo, hi - lo, mine, H5P_DEFAULT);
                for (int q = 1; q < size; q++) {
                    hsize_t a = n * (hsize_t)q / (hsize_t)size, b = n * (hsize_t)(q + 1) / (hsize_t)size;
                    MPI_Recv(buf, (int)(b - a), MPI_DOUBLE, q, j, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                    put(d, a, b - a, buf, H5P_DEFAULT);
                }
                H5Dclose(d);
            }
            H5Fclose(f);
        } else {
            for (int j = 0; j < cols; j++) MPI_Send(mine, (int)(hi - lo), MPI_DOUBLE, 0, j, MPI_COMM_WORLD);
        }
        MPI_Barrier(MPI_COMM_WORLD);
        double t1 = now() - t0;
        /* parallel HDF5: every rank its hyperslab, collectively */
        snprintf(path, sizeof path, "%s/parallel.h5", argv[4]);
        MPI_Barrier(MPI_COMM_WORLD);
        t0 = now();
        hid_t fa = H5Pcreate(H5P_FILE_ACCESS);
        H5Pset_fapl_mpio(fa, MPI_COMM_WORLD, MPI_INFO_NULL);
        hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, fa);
        hid_t xfer = H5Pcreate(H5P_DATASET_XFER);
        H5Pset_dxpl_mpio(xfer, H5FD_MPIO_COLLECTIVE);
        for (int j = 0; j < cols; j++) {
            hid_t d = column(f, j, n);
            put(d, lo, hi - lo, mine, xfer);
            H5Dclose(d);
        }
        H5Pclose(xfer), H5Fclose(f), H5Pclose(fa);
        MPI_Barrier(MPI_COMM_WORLD);
        double t2 = now() - t0;
        if (t1 < best[0]) best[0] = t1;
        if (t2 < best[1]) best[1] = t2;
    }
    if (rank == 0)
        printf("N %llu  columns %d  ranks %d  best of %d: gather onto rank 0 %.3f s, parallel HDF5 (MPI-IO, collective) "
               "%.3f s\n", (unsigned long long)n, cols, size, repeats, best[0], best[1]);
    free(mine), free(buf);
    MPI_Finalize();
    return 0;
}
