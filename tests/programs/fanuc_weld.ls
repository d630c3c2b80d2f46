/PROG  WELD_SEAM
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "Fixture 1 seam";
PROG_SIZE	= 2318;
CREATE		= DATE 26-11-18  TIME 09:12:40;
MODIFIED	= DATE 26-11-20  TIME 14:03:12;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 22;
MEMORY_SIZE	= 2802;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,1,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/APPL
  ARC Welding Equipment : 1,*,*,*,*;
/MN
   1:  !Seam on fixture 1, torch UT 1 ;
   2:  UFRAME_NUM=1 ;
   3:  UTOOL_NUM=1 ;
   4:J P[1:HOME] 100% FINE    ;
   5:J P[2] 50% CNT50    ;
   6:L P[3:seam start] 500mm/sec FINE    ;
   7:  Arc Start[1] ;
   8:L P[4] 10mm/sec CNT100    ;
   9:C P[5]    
    :  P[6] 10mm/sec FINE    ;
  10:  Arc End[1] ;
  11:L P[6] 100mm/sec FINE Offset,PR[1:Lift 30]    ;
  12:L P[7] 200mm/sec CNT50 Tool_Offset,PR[2:Back 20]    ;
  13:  //L P[8] 100mm/sec FINE    ;
  14:  UFRAME_NUM=2 ;
  15:J P[8] 50% FINE    ;
  16:  UFRAME_NUM=3 ;
  17:L P[9:spare fixture] 100mm/sec FINE    ;
  18:L P[10] 100mm/sec FINE INC    ;
  19:J PR[3:Service] 100% FINE    ;
  20:J P[11] 100% FINE    ;
  21:  UFRAME_NUM=0 ;
  22:J P[1:HOME] 100% FINE    ;
/POS
P[1:"HOME"]{
   GP1:
	UF : 0, UT : 1,	
	J1=     13.846 deg,	J2=    -73.539 deg,	J3=    117.165 deg,
	J4=     19.659 deg,	J5=    -45.347 deg,	J6=    -14.094 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    249.186  mm,	Y =    -28.397  mm,	Z =    450.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[3:"seam start"]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    249.186  mm,	Y =    -28.397  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[4]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    370.788  mm,	Y =    -17.776  mm,	Z =    350.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[5]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    444.090  mm,	Y =      9.186  mm,	Z =    400.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[6]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    457.391  mm,	Y =    -67.776  mm,	Z =    450.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[7]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    300.000  mm,	Y =       .000  mm,	Z =    420.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
};
P[8]{
   GP1:
	UF : 2, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    480.000  mm,	Y =    -20.000  mm,	Z =    320.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[9:"spare fixture"]{
   GP1:
	UF : 3, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    100.000  mm,	Y =     50.000  mm,	Z =    200.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =       .000 deg
};
P[10]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =       .000  mm,	Y =       .000  mm,	Z =     20.000  mm,
	W =       .000 deg,	P =       .000 deg,	R =       .000 deg
};
P[11]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =    320.000  mm,	Y =    -40.000  mm,	Z =    380.000  mm,
	W =       .000 deg,	P =     90.000 deg,	R =    -30.000 deg
   GP2:
	UF : 0, UT : 1,	
	J1=    90.000 deg,	J2=      .000 deg
};
/END
