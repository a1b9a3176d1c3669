/* gi_exit.h - process exit codes shared by every gi tool.
 * The table is repeated in each man page (docs/man/gi-*.md, EXIT STATUS). */
#ifndef GI_EXIT_H
#define GI_EXIT_H

#define GI_EXIT_OK 0       /* success; gi-compare: inputs match */
#define GI_EXIT_DIFFER 1   /* gi-compare only: difference beyond tolerance */
#define GI_EXIT_USAGE 2    /* bad command line */
#define GI_EXIT_DATA 3     /* bad input data: corrupt, wrong version, stale, malformed */
#define GI_EXIT_SYSTEM 4   /* system failure: I/O, memory, Embree/OSMesa/OIIO */

#endif
