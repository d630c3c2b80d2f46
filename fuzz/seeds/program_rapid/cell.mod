%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE Cell
  ! A welding gun 200 mm along the flange's z axis, and a fixture frame.
  PERS tooldata gun:=[TRUE,[[0,0,200],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata fixture:=[FALSE,TRUE,"",[[1000,0,500],[1,0,0,0]],[[0,100,0],[1,0,0,0]]];
  CONST robtarget p10:=[[700,200,700],[0.707106781,0,0.707106781,0],[0,0,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PERS robtarget p20:=[[800.5,300.25,650],[0.70710678,0,0.70710678,0],[0,0,-1,1],[9E9,9E9,9E9,9E9,9E9,9E9]];
  VAR robtarget p30 := [ [900, 350, 800], [0.7071068, 0, 0.7071068, 0], [0, 0, -1, 1], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9] ];
  CONST robtarget pSpare:=[[850,300,700],[0.707106781,0,0.707106781,0],[0,0,-1,1],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST jointtarget jStart:=[[10,-70,95,0,-25,0],[9E9,9E9,9E9,9E9,9E9,9E9]];

  PROC main()
    MoveAbsJ jStart\NoEOffs, v1000, z50, tool0;
    MoveJ p10, v1000, z50, gun\WObj:=fixture;
    MoveL p20, v200, z10, gun\WObj:=fixture; ! seam
    MoveC p30, [[950,400,750],[0.707106781,0,0.707106781,0],[0,0,-1,1],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, gun\WObj:=fixture;
    MoveL Offs(p20,0,0,50), v200, fine, gun\WObj:=fixture;
  ENDPROC
ENDMODULE
