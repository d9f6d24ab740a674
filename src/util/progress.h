/* The one progress bar of wavefuel's programs: the text of a bar and its estimate of the time left; the program
 * prints it (nothing in the library prints). Internal to wavefuel. */
#ifndef WAVEFUEL_PROGRESS_H
#define WAVEFUEL_PROGRESS_H

#define WF_PROGRESS_CELLS 30 /* cells of the bar */

/* bar (at least WF_PROGRESS_CELLS + 1 bytes) receives '#' for the done fraction frac (clamped to [0, 1]) and '.'
 * for the rest. Returns the wall time left in s, extrapolated from wall_s spent on frac (0 while frac is 0). */
double wf_progress_bar(double frac, double wall_s, char *bar);

#endif
