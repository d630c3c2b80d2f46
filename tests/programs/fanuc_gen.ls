/PROG  RASTER_GEN
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "";
PROG_SIZE	= 0;
CREATE		= DATE 26-11-21  TIME 10:00:00;
MODIFIED	= DATE 26-11-21  TIME 10:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 43;
MEMORY_SIZE	= 0;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/MN
   1:  UFRAME_NUM=2 ;
   2:  UTOOL_NUM=2 ;
   3:J P[1] 100% FINE    ;
   4:L P[2] 800mm/sec CNT100    ;
   5:L P[3] 800mm/sec CNT100    ;
   6:L P[4] 800mm/sec CNT100    ;
   7:L P[5] 800mm/sec CNT100    ;
   8:L P[6] 800mm/sec CNT100    ;
   9:L P[7] 800mm/sec CNT100    ;
  10:L P[8] 800mm/sec CNT100    ;
  11:L P[9] 800mm/sec CNT100    ;
  12:L P[10] 800mm/sec CNT100    ;
  13:L P[11] 800mm/sec CNT100    ;
  14:L P[12] 800mm/sec CNT100    ;
  15:L P[13] 800mm/sec CNT100    ;
  16:L P[14] 800mm/sec CNT100    ;
  17:L P[15] 800mm/sec CNT100    ;
  18:L P[16] 800mm/sec CNT100    ;
  19:L P[17] 800mm/sec CNT100    ;
  20:L P[18] 800mm/sec CNT100    ;
  21:L P[19] 800mm/sec CNT100    ;
  22:L P[20] 800mm/sec CNT100    ;
  23:L P[21] 800mm/sec CNT100    ;
  24:L P[22] 800mm/sec CNT100    ;
  25:L P[23] 800mm/sec CNT100    ;
  26:L P[24] 800mm/sec CNT100    ;
  27:L P[25] 800mm/sec CNT100    ;
  28:L P[26] 800mm/sec CNT100    ;
  29:L P[27] 800mm/sec CNT100    ;
  30:L P[28] 800mm/sec CNT100    ;
  31:L P[29] 800mm/sec CNT100    ;
  32:L P[30] 800mm/sec CNT100    ;
  33:L P[31] 800mm/sec CNT100    ;
  34:L P[32] 800mm/sec CNT100    ;
  35:L P[33] 800mm/sec CNT100    ;
  36:L P[34] 800mm/sec CNT100    ;
  37:L P[35] 800mm/sec CNT100    ;
  38:L P[36] 800mm/sec CNT100    ;
  39:A P[37] 300mm/sec CNT100    ;
  40:A P[38] 300mm/sec CNT100    ;
  41:A P[39] 300mm/sec FINE    ;
  42:C P[40]    
    :  P[41] 300mm/sec FINE    ;
  43:J P[1] 100% FINE    ;
/POS
P[1]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =   -275.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[2]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =   -275.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[3]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =   -275.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[4]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =   -275.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[5]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    -75.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[6]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    -75.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[7]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    -75.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[8]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    -75.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[9]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    125.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[10]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    125.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[11]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    125.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[12]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    125.000  mm,	Z =    100.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[13]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    125.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[14]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    125.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[15]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    125.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[16]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    125.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[17]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    -75.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[18]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    -75.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[19]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    -75.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[20]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    -75.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[21]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =   -275.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[22]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =   -275.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[23]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =   -275.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[24]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =   -275.000  mm,	Z =    300.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[25]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =   -275.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[26]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =   -275.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[27]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =   -275.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[28]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =   -275.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[29]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    -75.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[30]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    -75.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[31]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    -75.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[32]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    -75.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[33]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    220.000  mm,	Y =    125.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[34]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    125.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[35]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =    125.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[36]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    670.000  mm,	Y =    125.000  mm,	Z =    500.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[37]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    570.000  mm,	Y =    -75.000  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[38]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    520.000  mm,	Y =     11.603  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[39]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    420.000  mm,	Y =     11.603  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[40]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.000  mm,	Y =    -75.000  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[41]{
   GP1:
	UF : 2, UT : 2,		CONFIG : 'F U T, 0, 0, 0',
	X =    470.000  mm,	Y =   -175.000  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
/END
